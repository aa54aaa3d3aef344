"""Occupancy grids: frames, walls, and the ROS map_server format (YAML + PGM/PNG)."""

from __future__ import annotations

import math
import pickle
import sys

import numpy as np
import pytest

from beacon_sim.core.occupancy import (
    FREE,
    MAX_CELLS,
    OCCUPIED,
    UNKNOWN,
    MapError,
    OccupancyGrid,
    from_walls,
    load_map,
    parse_map_yaml,
    save_map,
)
from beacon_sim.errors import BeaconSimError


def sample_grid() -> OccupancyGrid:
    rng = np.random.default_rng(11)
    cells = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=(7, 12))
    return OccupancyGrid(cells, 0.05, (-1.5, 2.25, 0.3))


def write_map(tmp_path, pixels: np.ndarray, **keys) -> object:
    """A P5 PGM (top line first) and a YAML naming it, with map_server's keys."""
    h, w = pixels.shape
    (tmp_path / "m.pgm").write_bytes(f"P5\n{w} {h}\n255\n".encode() + pixels.astype(np.uint8).tobytes())
    meta = {"image": "m.pgm", "resolution": 0.1, "origin": "[0.0, 0.0, 0.0]", "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196}
    meta.update(keys)
    text = "".join(f"{k}: {v}\n" for k, v in meta.items() if v is not None)
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return path


def test_world_and_cell_frames():
    g = OccupancyGrid(np.zeros((4, 6), dtype=np.int8), 0.5, (1.0, 2.0, math.pi / 2))
    # Rotated a quarter turn: the grid's u axis is world +y, its v axis world -x.
    np.testing.assert_allclose(g.grid_to_world([2.0, 0.0]), [1.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(g.grid_to_world([0.0, 2.0]), [0.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(g.cell_to_world([0, 0]), [0.75, 2.25], atol=1e-12)
    rng = np.random.default_rng(0)
    xy = rng.uniform(-5, 5, size=(50, 2))
    np.testing.assert_allclose(g.grid_to_world(g.world_to_grid(xy)), xy, atol=1e-12)
    rc = np.array([[0, 0], [3, 5], [2, 1]])
    np.testing.assert_array_equal(g.world_to_cell(g.cell_to_world(rc)), rc)
    assert g.in_grid(np.array([[3, 5], [4, 0], [0, -1]])).tolist() == [True, False, False]
    assert g.size_m == (3.0, 2.0)


def test_is_occupied_and_pickling():
    cells = np.zeros((3, 3), dtype=np.int8)
    cells[1, 2] = OCCUPIED
    g = OccupancyGrid(cells, 1.0)
    assert g.is_occupied([[2.5, 1.5], [0.5, 0.5], [9.0, 9.0]]).tolist() == [True, False, False]
    _ = g.occupied
    again = pickle.loads(pickle.dumps(g))
    np.testing.assert_array_equal(again.cells, g.cells)
    with pytest.raises(ValueError):
        g.cells[0, 0] = OCCUPIED   # a value: read-only


def test_bad_grids():
    with pytest.raises(MapError, match="resolution"):
        OccupancyGrid(np.zeros((2, 2), dtype=np.int8), 0.0)
    with pytest.raises(MapError, match="0 \\(free\\), 100"):
        OccupancyGrid(np.full((2, 2), 7, dtype=np.int8), 1.0)
    with pytest.raises(MapError, match="2-D"):
        OccupancyGrid(np.zeros(4, dtype=np.int8), 1.0)


def test_walls_segments_and_polygons():
    g = from_walls((0, 0, 4, 3), 0.5, segments=[[(0.25, 0.25), (3.75, 0.25)], [(1.0, 0.0), (1.0, 3.0)]],
                   polygons=[[(2.5, 1.5), (3.5, 1.5), (3.5, 2.5), (2.5, 2.5)]])
    assert g.shape == (6, 8) and g.origin == (0.0, 0.0, 0.0)
    assert g.occupied[0, :].all()              # the horizontal segment fills row 0
    assert g.occupied[:, 2].all()              # x = 1.0 is the left edge of column 2
    assert not g.occupied[1:, 1].any()
    # The square [2.5, 3.5] x [1.5, 2.5]: filled (cells 3-4 x 5-6), and its outline's top and
    # right edges lie on grid lines, so they occupy the cells above and right of them.
    assert g.occupied[3:6, 5:8].all()
    assert g.occupied.sum() == 8 + 5 + 9       # nothing else
    # A slanted segment marks exactly the cells it passes through, and where it passes a grid
    # corner (here (2, 1)) the two cells beside the corner: a wall with no diagonal gap.
    s = from_walls((0, 0, 4, 4), 1.0, segments=[[(0.5, 0.5), (3.5, 1.5)]])
    assert set(zip(*np.nonzero(s.occupied), strict=True)) == {(0, 0), (0, 1), (1, 2), (1, 3),
                                                               (1, 1), (0, 2)}
    t = from_walls((0, 0, 4, 4), 1.0, segments=[[(0.5, 0.5), (3.5, 1.2)]])   # no corner met
    assert set(zip(*np.nonzero(t.occupied), strict=True)) == {(0, 0), (0, 1), (0, 2), (1, 2), (1, 3)}


def test_a_room_outline_on_the_bounds_has_four_walls():
    g = from_walls((0, 0, 10, 4), 0.05, segments=[[(0, 0), (10, 0), (10, 4), (0, 4), (0, 0)]])
    assert g.shape == (80, 200)
    occ = g.occupied
    assert occ[0, :].all() and occ[-1, :].all() and occ[:, 0].all() and occ[:, -1].all()
    assert not occ[1:-1, 1:-1].any()


def test_walls_bad_input():
    with pytest.raises(MapError, match="bounds"):
        from_walls((0, 0, 0, 1), 0.1)
    with pytest.raises(MapError, match="segment"):
        from_walls((0, 0, 1, 1), 0.1, segments=[[(0, 0)]])
    with pytest.raises(MapError, match="over the cap"):
        from_walls((0, 0, 1000, 1000), 0.01)


def test_thresholds_and_negate_by_hand(tmp_path):
    # Grey values and their occupancy p = (255 - v) / 255: 0 -> 1.0, 80 -> 0.686, 100 -> 0.608,
    # 205 -> 0.196 (not below free_thresh 0.196), 210 -> 0.176, 254 -> 0.004.
    pixels = np.array([[0, 80, 100, 205, 210, 254]])
    g = load_map(write_map(tmp_path, pixels))
    assert g.cells[0].tolist() == [OCCUPIED, OCCUPIED, UNKNOWN, UNKNOWN, FREE, FREE]
    g = load_map(write_map(tmp_path, pixels, negate=1))   # p = v / 255
    assert g.cells[0].tolist() == [FREE, UNKNOWN, UNKNOWN, OCCUPIED, OCCUPIED, OCCUPIED]
    g = load_map(write_map(tmp_path, pixels, occupied_thresh=0.9, free_thresh=0.5))
    assert g.cells[0].tolist() == [OCCUPIED, UNKNOWN, UNKNOWN, FREE, FREE, FREE]


def test_the_image_top_line_is_the_last_row(tmp_path):
    pixels = np.array([[0, 254], [254, 254]])   # occupied pixel top-left
    g = load_map(write_map(tmp_path, pixels, origin="[2.0, -1.0, 0.0]", resolution=0.5))
    assert g.cells[1, 0] == OCCUPIED and g.cells[0, 0] == FREE
    assert g.is_occupied([2.25, -0.25]) and not g.is_occupied([2.25, -0.75])
    assert g.origin == (2.0, -1.0, 0.0) and g.resolution == 0.5


@pytest.mark.parametrize("negate", [0, 1])
@pytest.mark.parametrize("ascii_pgm", [False, True])
def test_map_server_round_trip(tmp_path, negate, ascii_pgm):
    g = sample_grid()
    image = save_map(g, tmp_path / "floor.yaml", negate=negate, ascii_pgm=ascii_pgm,
                     occupied_thresh=0.7, free_thresh=0.25)
    assert image.read_bytes()[:2] == (b"P2" if ascii_pgm else b"P5")
    meta = parse_map_yaml((tmp_path / "floor.yaml").read_text(), "floor.yaml")
    assert meta["negate"] == negate and meta["occupied_thresh"] == 0.7 and meta["free_thresh"] == 0.25
    back = load_map(tmp_path / "floor.yaml")
    np.testing.assert_array_equal(back.cells, g.cells)
    assert back.origin == g.origin and back.resolution == g.resolution


def test_png_maps(tmp_path, monkeypatch):
    from PIL import Image  # Pillow is a test dependency; for users the PNG path is optional
    rgb = np.zeros((2, 3, 3), dtype=np.uint8)
    rgb[:] = 254
    rgb[0, 0] = (0, 0, 0)
    rgb[1, 2] = (205, 205, 205)
    Image.fromarray(rgb, "RGB").save(tmp_path / "m.png")
    path = write_map(tmp_path, np.zeros((1, 1)), image="m.png")
    g = load_map(path)
    assert g.cells.tolist() == [[FREE, FREE, UNKNOWN], [OCCUPIED, FREE, FREE]]
    grey16 = np.array([[0, 65535], [30000, 65535]], dtype=np.uint16)   # p = 1, 0 / 0.54, 0
    Image.fromarray(grey16).save(tmp_path / "m.png")
    assert load_map(path).cells.tolist() == [[UNKNOWN, FREE], [OCCUPIED, FREE]]   # row 0: bottom
    monkeypatch.setitem(sys.modules, "PIL", None)   # as if Pillow were not installed
    with pytest.raises(MapError, match=r"(?i)needs pillow"):
        load_map(path)


def one_line(exc: pytest.ExceptionInfo) -> str:
    msg = str(exc.value)
    assert "\n" not in msg and isinstance(exc.value, BeaconSimError)
    return msg


@pytest.mark.parametrize(("keys", "words"), [
    ({"resolution": None}, "missing key 'resolution'"),
    ({"origin": None}, "missing key 'origin'"),
    ({"occupied_thresh": 1.5}, "'occupied_thresh' must be in [0, 1]"),
    ({"free_thresh": -0.1}, "'free_thresh' must be in [0, 1]"),
    ({"free_thresh": 0.7}, "'free_thresh' (0.7) must be below 'occupied_thresh'"),
    ({"resolution": 0}, "'resolution' must be > 0"),
    ({"resolution": "fine"}, "'resolution' must be a number"),
    ({"origin": "[1, 2]"}, "'origin' must be [x, y, yaw]"),
    ({"negate": 2}, "'negate' must be 0 or 1"),
    ({"mode": "scale"}, "'mode' must be 'trinary'"),
    ({"image": "nowhere.pgm"}, "nowhere.pgm: cannot read the map image"),
])
def test_bad_yaml_names_the_file_and_key(tmp_path, keys, words):
    path = write_map(tmp_path, np.full((2, 2), 254), **keys)
    with pytest.raises(MapError) as exc:
        load_map(path)
    msg = one_line(exc)
    assert words in msg
    assert "m.yaml" in msg or "nowhere.pgm" in msg


def test_bad_images(tmp_path):
    path = write_map(tmp_path, np.full((2, 2), 254))
    (tmp_path / "m.pgm").write_bytes(b"P5\n3 2\n255\n" + bytes(5))   # one byte short
    with pytest.raises(MapError) as exc:
        load_map(path)
    assert "m.pgm" in one_line(exc) and "needs 6" in str(exc.value)
    (tmp_path / "m.pgm").write_bytes(b"P2\n2 2\n255\n1 2 3\n")
    with pytest.raises(MapError, match="3 values, the header's 2x2 needs 4"):
        load_map(path)
    (tmp_path / "m.pgm").write_bytes(b"P5\n100000 100000\n255\n")
    with pytest.raises(MapError, match=f"over the cap of {MAX_CELLS}"):
        load_map(path)
    (tmp_path / "m.pgm").write_bytes(b"GIF89a")
    with pytest.raises(MapError, match="not a PGM"):
        load_map(path)
    with pytest.raises(MapError, match="cannot read the map file"):
        load_map(tmp_path / "absent.yaml")
    (tmp_path / "big.yaml").write_text("# " + "x" * 1_000_001)
    with pytest.raises(MapError, match="a map file holds at most 1,000,000"):
        load_map(tmp_path / "big.yaml")


def test_pgm_comments_and_16_bit(tmp_path):
    path = write_map(tmp_path, np.full((1, 2), 254))
    raster = np.array([0, 65535], dtype=">u2").tobytes()
    (tmp_path / "m.pgm").write_bytes(b"P5\n# a comment\n2 1 # trailing\n65535\n" + raster)
    assert load_map(path).cells.tolist() == [[OCCUPIED, FREE]]


def test_yaml_comments_and_quotes():
    meta = parse_map_yaml("# map\nimage: 'a b.pgm'  # the image\norigin: [1, -2.5, 0]\n", "x.yaml")
    assert meta == {"image": "a b.pgm", "origin": [1, -2.5, 0]}
    with pytest.raises(MapError, match=r"x\.yaml: .*'key: value'"):
        parse_map_yaml("just words\n", "x.yaml")


def test_the_example_of_docs_maps_runs():
    """docs/maps.md's Python block, run as written: the truth scores above a far pose."""
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "maps.md").read_text()
    code = doc.split("```python\n", 1)[1].split("```", 1)[0]
    scope: dict = {}
    exec(compile(code, "docs/maps.md", "exec"), scope)
    assert scope["ranges"].shape == (180,) and scope["ranges"].min() > 0
    assert scope["log_w"][0] > scope["log_w"][1]
