"""map_server YAML files: PyYAML (the ``maps`` extra) reads every valid form, and the base
install's hand reader gives the same mapping for the flat form map_server writes.

The example files are written here from the map_server format (keys image, resolution,
origin [x, y, yaw], negate, occupied_thresh, free_thresh, optional mode), in the forms ROS 1's
map_saver, ROS 2's nav2 map_saver and hand-edited maps take."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core import optional
from beacon_sim.core.occupancy import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    MapError,
    load_map,
    parse_flat_map_yaml,
    parse_map_yaml,
    write_pgm,
)

#: A 2 x 3 image, top line first: free (254), occupied (0), unknown (205).
PIXELS = np.array([[254, 0, 205], [0, 254, 254]], dtype=np.uint8)
#: The grid it makes (row 0 the bottom line), negate 0.
CELLS = [[OCCUPIED, FREE, FREE], [FREE, OCCUPIED, UNKNOWN]]

#: map_server's flat form, as map savers write it: both readers take these.
FLAT = {
    "ros1_map_saver": "image: m.pgm\nresolution: 0.050000\norigin: [-10.000000, -10.000000, 0.000000]\n"
                      "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n\n",
    "ros2_map_saver": "image: m.pgm\nmode: trinary\nresolution: 0.05\norigin: [-10, -10, 0]\n"
                      "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    "commented": "# the lab, saved by hand\nimage: m.pgm   # beside this file\nresolution: 0.1\n"
                 "origin: [ 1.5, -2.0, 0.3 ]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    "document_start": "---\nimage: m.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"
                      "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    "quoted": "image: \"m.pgm\"\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
              "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: 'trinary'\n",
    "exponent": "image: m.pgm\nresolution: 5e-2\norigin: [0, 0, 0]\nnegate: 0\n"
                "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
    "boolean_negate": "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: false\n"
                      "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
}
#: Valid YAML beyond the flat form: PyYAML only.
RICH = {
    "block_list_origin": "image: m.pgm\nresolution: 0.05\norigin:\n  - -10.0\n  - -10.0\n  - 0.0\n"
                         "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    "one_line_mapping": "{image: m.pgm, resolution: 0.05, origin: [0, 0, 0], negate: 0, "
                        "occupied_thresh: 0.65, free_thresh: 0.196}\n",
    "document_end_and_indent": "---\nimage:   m.pgm\nresolution:\n  0.05\norigin: [0, 0, 0]\n"
                               "occupied_thresh: 0.65\nfree_thresh: 0.196\n...\n",
}


@pytest.fixture
def folder(tmp_path):
    write_pgm(tmp_path / "m.pgm", PIXELS)
    return tmp_path


def without_pyyaml(monkeypatch):
    monkeypatch.setitem(optional._FOUND, "yaml", None)


@pytest.mark.parametrize("name", sorted(FLAT))
def test_both_readers_agree_on_the_flat_form(name, folder, monkeypatch):
    text = FLAT[name]
    by_yaml = parse_map_yaml(text, name)
    assert by_yaml == parse_flat_map_yaml(text, name)
    (folder / "m.yaml").write_text(text)
    grid = load_map(folder / "m.yaml")
    assert grid.cells.tolist() == CELLS
    assert grid.resolution == by_yaml["resolution"]
    without_pyyaml(monkeypatch)
    assert load_map(folder / "m.yaml") == grid


@pytest.mark.parametrize("name", sorted(RICH))
def test_pyyaml_reads_every_valid_form(name, folder, monkeypatch):
    (folder / "m.yaml").write_text(RICH[name])
    grid = load_map(folder / "m.yaml")
    assert grid.cells.tolist() == CELLS and grid.resolution == 0.05
    without_pyyaml(monkeypatch)  # the hand reader says what it cannot read and what can
    with pytest.raises(MapError, match=r"m\.yaml: line \d+: .*pip install 'pyyaml'"):
        load_map(folder / "m.yaml")


def test_negate_true_inverts(folder):
    (folder / "m.yaml").write_text(FLAT["boolean_negate"].replace("negate: false", "negate: true"))
    grid = load_map(folder / "m.yaml")
    # p = value / 255: 254 and 205 (0.80) are occupied, 0 free
    assert grid.cells.tolist() == [[FREE, OCCUPIED, OCCUPIED], [OCCUPIED, FREE, OCCUPIED]]


def test_a_yaml_error_is_one_line(folder):
    (folder / "m.yaml").write_text("image: m.pgm\norigin: [0, 0\nresolution: 0.05\n")
    with pytest.raises(MapError) as err:
        load_map(folder / "m.yaml")
    text = str(err.value)
    assert "\n" not in text and "m.yaml: line" in text and "not valid YAML" in text
    (folder / "m.yaml").write_text("- a list\n- not a map\n")
    with pytest.raises(MapError, match="expected a mapping"):
        load_map(folder / "m.yaml")
