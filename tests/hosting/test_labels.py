"""Filter names: ``--filter alice=./alice.py:MyEkf`` labels a filter;
unlabelled file filters whose class names clash take their file's name."""

from __future__ import annotations

import json

import pytest
from student_filters import write_class

from beacon_sim.cli.main import main
from beacon_sim.hosting.loading import filter_display_name, filter_names, split_label


@pytest.fixture(scope="module")
def klass(tmp_path_factory):
    return write_class(tmp_path_factory.mktemp("labels"), ["alice", "bob", "carol"])


def test_split_label():
    assert split_label("alice=./alice.py:MyEkf") == ("alice", "./alice.py:MyEkf")
    assert split_label("ekf") == (None, "ekf")
    assert split_label("./a=b/x.py:C") == (None, "./a=b/x.py:C")
    assert filter_display_name("team-7=ekf") == "team-7"


def test_clashing_class_names_take_the_file_name():
    specs = ["a/alice.py:MyEkf", "b/bob.py:MyEkf", "c/carol.py:MyEkf", "ekf", "ekf"]
    assert filter_names(specs) == ["alice", "bob", "carol", "ekf", "ekf'"]
    assert filter_names(["a/alice.py:MyEkf", "ekf"]) == ["MyEkf", "ekf"]
    assert filter_names(["x/alice.py:MyEkf", "y/alice.py:MyEkf"]) == ["alice", "alice'"]
    assert filter_names(["me=a/alice.py:MyEkf", "b/bob.py:MyEkf"]) == ["me", "MyEkf"]


def test_run_uses_labels_and_file_names(klass, capsys):
    assert main(["run", "default", "--duration", "1", "--json",
                 "--filter", f"star={klass}/alice.py:MyEkf",
                 "--filter", f"{klass}/bob.py:MyEkf", "--filter", f"{klass}/carol.py:MyEkf",
                 "--set", "star.joseph=true"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out["filters"]) == ["star", "bob", "carol"]


def test_check_accepts_a_labelled_spec(klass, capsys):
    assert main(["check", f"alice={klass}/alice.py:MyEkf"]) == 0
