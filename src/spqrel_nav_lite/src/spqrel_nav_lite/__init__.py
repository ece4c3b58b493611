"""spqrel_nav_lite: map server, localisation and navigation nodes behind move_base."""
