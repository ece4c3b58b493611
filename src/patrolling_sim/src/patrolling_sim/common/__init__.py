"""The bottom layer: what every other layer may use.

- :mod:`~patrolling_sim.common.errors`   -- the input error types (one-line messages)
- :mod:`~patrolling_sim.common.protocol` -- the ``/results`` message numbers of the original's
  protocol
- :mod:`~patrolling_sim.common.paths`    -- where shipped maps, parameters and MSP files live
- :mod:`~patrolling_sim.common.textfile` -- reading input text and YAML files with one-line errors
- :mod:`~patrolling_sim.common.cli`      -- the command-line tools' parser, logging and exit codes
"""
