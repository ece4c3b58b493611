"""Map loader: thresholds, negate, origin, bottom-up rows, malformed input."""
import cv2
import numpy as np
import pytest

from patrolling_sim import paths
from patrolling_sim.errors import MapFormatError
from patrolling_sim.mapio import FREE, OCCUPIED, UNKNOWN, load_map


def _write_map(tmp_path, img, **meta):
    cv2.imwrite(str(tmp_path / "m.pgm"), img)
    body = {"image": "m.pgm", "resolution": 0.5, "origin": [1.0, 2.0, 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196}
    body.update(meta)
    import yaml
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(body))
    return str(tmp_path / "m.yaml")


def test_thresholds_and_row_order(tmp_path):
    img = np.array([[0, 254], [205, 128]], dtype=np.uint8)   # top row first
    occ = load_map(_write_map(tmp_path, img))
    # bottom image row becomes data row 0
    assert occ.data.tolist() == [[UNKNOWN, UNKNOWN], [OCCUPIED, FREE]]
    assert occ.cell_state(1.1, 2.1) == "unknown"
    assert occ.cell_state(1.1, 2.6) == "occupied"
    assert occ.cell_state(1.6, 2.6) == "free"
    assert occ.cell_state(0.9, 2.1) == "out-of-map"
    assert occ.cell_to_world(1, 1) == (1.75, 2.75)


def test_negate(tmp_path):
    img = np.array([[0, 254]], dtype=np.uint8)
    occ = load_map(_write_map(tmp_path, img, negate=1))
    assert occ.data.tolist() == [[FREE, OCCUPIED]]


def test_shipped_maps_load():
    for name in paths.available_maps():
        occ = load_map(paths.map_files(name)[0])
        assert (occ.data == FREE).sum() > 0 and (occ.data == OCCUPIED).sum() > 0
    occ = load_map(paths.map_files("ctcv")[0])
    assert occ.origin[:2] == (-29.675, -7.4)


def test_clearance(tmp_path):
    img = np.full((20, 20), 254, np.uint8)
    img[:, 0] = 0
    occ = load_map(_write_map(tmp_path, img, origin=[0, 0, 0]))
    # cell (10, 10): 10 cells from the wall column and from the border beyond column 19;
    # clearance is measured to the obstacle cell's edge: 9.5 cells of 0.5 m
    assert occ.clearance_at(5.25, 5.25) == pytest.approx(4.75)
    assert occ.clearance_at(0.75, 5.25) == pytest.approx(0.25)   # next to the wall


@pytest.mark.parametrize("meta,needle", [
    ({"resolution": "abc"}, "key 'resolution' must be a number"),
    ({"resolution": -1}, "must be positive"),
    ({"origin": [0, 0]}, "key 'origin' must be [x, y, yaw]"),
    ({"image": "missing.pgm"}, "missing.pgm' not found"),
    ({"occupied_thresh": 1.5}, "outside [0.0, 1.0]"),
    ({"free_thresh": 0.9, "occupied_thresh": 0.5}, "free_thresh 0.9 is above"),
    ({"negate": 3}, "key 'negate' must be 0 or 1"),
])
def test_malformed_yaml(tmp_path, meta, needle):
    path = _write_map(tmp_path, np.zeros((4, 4), np.uint8), **meta)
    with pytest.raises(MapFormatError) as ei:
        load_map(path)
    assert needle in str(ei.value) and "\n" not in str(ei.value)


def test_missing_key_and_file(tmp_path):
    (tmp_path / "k.yaml").write_text("image: m.pgm\nresolution: 0.1\n")
    with pytest.raises(MapFormatError, match="missing key 'origin'"):
        load_map(str(tmp_path / "k.yaml"))
    with pytest.raises(MapFormatError, match="map yaml not found"):
        load_map(str(tmp_path / "none.yaml"))
    (tmp_path / "bad.yaml").write_text("image: [unclosed\n")
    with pytest.raises(MapFormatError, match="invalid YAML"):
        load_map(str(tmp_path / "bad.yaml"))
    (tmp_path / "garbage.pgm").write_bytes(b"not an image")
    (tmp_path / "g.yaml").write_text("image: garbage.pgm\nresolution: 0.1\norigin: [0,0,0]\n")
    with pytest.raises(MapFormatError, match="cannot decode"):
        load_map(str(tmp_path / "g.yaml"))
