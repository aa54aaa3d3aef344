"""``beacon-sim mrclam ... --size WxH``: the MRCLAM window opens at that size (a bad size is
refused in one line before the run)."""

from __future__ import annotations

import pytest

pygame = pytest.importorskip("pygame")

from mrclam_helpers import make_folder  # noqa: E402

from beacon_sim.cli.main import main  # noqa: E402


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    f = tmp_path_factory.mktemp("mrclam") / "SyntheticSet"
    make_folder(f)
    return f


def test_the_window_takes_size(folder, tmp_path, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    shot = tmp_path / "m.png"
    assert main(["mrclam", str(folder), "--robot", "1", "--filter", "ekf", "--duration", "5",
                 "--frames", "3", "--screenshot", str(shot), "--size", "1024x768"]) == 0
    assert pygame.image.load(str(shot)).get_size() == (1024, 768)


def test_a_bad_size_is_refused_before_the_run(folder, capsys):
    assert main(["mrclam", str(folder), "--robot", "1", "--filter", "ekf", "--size", "big"]) == 2
    err = capsys.readouterr().err
    assert "--size 'big': expected WxH" in err and "\n" == err[-1] and err.count("\n") == 1
