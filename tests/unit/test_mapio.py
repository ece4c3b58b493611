"""Map loader: thresholds, negate, origin, bottom-up rows, malformed input."""
import cv2
import numpy as np
import pytest

from patrolling_sim.common import paths
from spqrel_nav_lite.errors import MapFormatError
from spqrel_nav_lite.mapio import FREE, OCCUPIED, UNKNOWN, load_map, read_image


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


def test_pgm_fast_path_equals_opencv_on_every_shipped_map():
    from spqrel_nav_lite.mapio import read_pgm8
    for name in paths.available_maps():
        image = load_map(paths.map_files(name)[0]).image_path
        fast = read_pgm8(image)
        assert fast is not None, f"{name}: the shipped map should take the fast path"
        ref = cv2.imread(image, cv2.IMREAD_UNCHANGED)
        assert fast.dtype == ref.dtype and np.array_equal(fast, ref), name


PIXELS = bytes([0, 254, 205, 128, 1, 255])


@pytest.mark.parametrize("header", [
    b"P5\n3 2\n255\n",
    b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n3 2\n255\n",
    b"P5 3 2 255 ",
    b"P5\r\n3\t2 # a comment after the height\r\n255\r",
    b"P5\n#c1\n#c2\n3\n2\n255\t",
])
def test_pgm_fast_path_headers_as_opencv_reads_them(tmp_path, header):
    from spqrel_nav_lite.mapio import read_pgm8
    p = tmp_path / "h.pgm"
    p.write_bytes(header + PIXELS)
    fast = read_pgm8(str(p))
    assert fast is not None and fast.tolist() == [[0, 254, 205], [128, 1, 255]]
    assert np.array_equal(fast, cv2.imread(str(p), cv2.IMREAD_UNCHANGED))


@pytest.mark.parametrize("data", [
    b"P2\n3 2\n255\n0 254 205\n128 1 255\n",       # ASCII PGM
    b"P5\n3 2\n65535\n" + bytes(12),                 # 16-bit
    b"P5\n3 2\n100\n" + bytes(6),                    # another maxval
    b"P5\n3 2\n255\n" + bytes(5),                    # truncated raster
    b"P5\n3 x\n255\n" + bytes(6),                    # malformed header
    b"\x89PNG\r\n",                                  # not a PGM
])
def test_other_images_are_left_to_opencv(tmp_path, data):
    from spqrel_nav_lite.mapio import read_pgm8
    p = tmp_path / "o.pgm"
    p.write_bytes(data)
    assert read_pgm8(str(p)) is None
    ref = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if ref is None or ref.size == 0:
        with pytest.raises(MapFormatError, match="cannot decode"):
            read_image(str(p))
    else:
        assert np.array_equal(read_image(str(p)), ref.astype(np.float64))


def test_clearance_of_one_cell_equals_the_grid_on_every_shipped_map():
    """clearance_at before the grid exists (a search around the cell) gives the grid's value,
    at 1500 random free cells and every fourth cell along the border of each map."""
    from spqrel_nav_lite.mapio import FREE as FREE_CELL, OccupancyMap
    rng = np.random.default_rng(0)
    for name in paths.available_maps():
        occ = load_map(paths.map_files(name)[0])
        grid = occ.clearance
        h, w = grid.shape
        rows, cols = np.nonzero(occ.data == FREE_CELL)
        pick = rng.choice(len(rows), size=min(1500, len(rows)), replace=False)
        cells = list(zip(cols[pick], rows[pick]))
        cells += [(i, j) for i in range(0, w, 4) for j in (0, h - 1)]
        cells += [(i, j) for j in range(0, h, 4) for i in (0, w - 1)]
        fresh = OccupancyMap(occ.data, occ.resolution, occ.origin)
        for i, j in cells:
            x, y = occ.cell_to_world(int(i), int(j))
            got = fresh.clearance_at(x, y)
            assert got == float(grid[j, i]), (name, i, j, got, float(grid[j, i]))
        assert fresh._clearance is None              # never computed the grid
