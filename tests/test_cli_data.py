"""Chapter 7 — `minimanc data generate` and `minimanc data show`."""

import shutil
from collections import namedtuple

import numpy as np
import pytest
from PIL import Image

from minimanc import world
from minimanc.cli import common as wcli
from minimanc.cli import main


def test_data_generate_and_show(tmp_path, capsys):
    out = tmp_path / "data"
    assert main(["data", "generate", "--scenes", "3", "--seed", "4", "--out", str(out),
                 "--workers", "1", "--quiet"]) == 0
    path = out / "world_3x4.npz"
    ds = world.load(path)
    assert len(ds) == 3 and ds.meta["seed"] == 4
    captured = capsys.readouterr()
    text = captured.out
    assert "generated 3 scenes" in text and ds.content_hash()[:16] in text
    assert "estimate for 3 scenes" in captured.err and "on disk" in captured.err
    assert sorted(p.name for p in out.iterdir()) == ["world_3x4.npz"]  # no temporary left
    show = tmp_path / "show"
    assert main(["data", "show", "--data", str(path), "--out", str(show), "--scene", "1"]) == 0
    gallery = Image.open(show / "gallery.png")
    assert gallery.size[0] > 300
    gif = Image.open(show / "scene.gif")
    assert gif.n_frames == world.T_STEPS
    frame = np.asarray(gif.convert("RGB"))
    assert frame.shape[0] == 4 * 64  # frames are upscaled 4x
    assert (show / "scene_map.png").exists()


def _usage_error(capsys, argv):
    """Run ``minimanc argv``: exit code 2 and exactly one line on stderr, no traceback."""
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith("estimate for")]
    assert code == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_data_show_rejects_a_bad_scene(tmp_path, capsys):
    out = tmp_path / "data"
    main(["data", "generate", "--scenes", "1", "--out", str(out), "--workers", "1", "--quiet"])
    capsys.readouterr()
    line = _usage_error(capsys, ["data", "show", "--data", str(out / "world_1x0.npz"),
                                 "--out", str(tmp_path / "show"), "--scene", "5"])
    assert "--scene must be in [0, 0]" in line
    assert not (tmp_path / "show" / "gallery.png").exists()  # refused before any work


@pytest.mark.parametrize("args,expected", [
    (["--scenes", "-3"], "--scenes must be an integer >= 1, got --scenes=-3"),
    (["--scenes", "0"], "--scenes must be an integer >= 1, got --scenes=0"),
    (["--size", "0"], "--size must be an integer >= 8, got --size=0"),
    (["--seed", "-1"], "--seed must be an integer >= 0, got --seed=-1"),
    (["--workers", "0"], "--workers must be an integer >= 1, got --workers=0"),
])
def test_data_generate_bad_numbers_are_one_line_exit_2(tmp_path, capsys, args, expected):
    line = _usage_error(capsys, ["data", "generate", "--out", str(tmp_path / "d"), "--quiet",
                                 *args])
    assert line == f"minimanc data: error: {expected}"
    assert not (tmp_path / "d").exists()


def test_data_generate_unwritable_out_is_refused_before_generating(tmp_path, capsys,
                                                                  monkeypatch):
    calls = []
    monkeypatch.setattr(world, "generate_file", lambda *a, **k: calls.append(a))
    monkeypatch.setattr(world, "estimate", lambda *a, **k: calls.append(a))
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a directory")
    line = _usage_error(capsys, ["data", "generate", "--out", str(blocker), "--quiet"])
    assert "file.txt: exists and is not a directory" in line
    line = _usage_error(capsys, ["data", "generate", "--out", str(blocker / "sub"), "--quiet"])
    assert "cannot create the directory" in line
    # a directory in which no file can be created (read-only file system, no permission)
    real = wcli.tempfile.TemporaryFile

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(wcli.tempfile, "TemporaryFile", denied)
    line = _usage_error(capsys, ["data", "generate", "--out", str(tmp_path), "--quiet"])
    assert "directory is not writable (Permission denied)" in line
    monkeypatch.setattr(wcli.tempfile, "TemporaryFile", real)
    assert calls == []  # nothing was estimated or generated


def test_data_generate_estimates_and_refuses_a_full_disk(tmp_path, capsys, monkeypatch):
    Usage = namedtuple("Usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**9, 10**9 - 10**6, 10**6))
    called = []
    monkeypatch.setattr(world, "generate_file", lambda *a, **k: called.append(a))
    code = main(["data", "generate", "--scenes", "100000", "--out", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 2, err
    assert err[0].startswith("estimate for 100000 scenes: about ") and " GB on disk" in err[0]
    assert "not enough free disk space" in err[1] and "0.00 GB are free" in err[1]
    assert called == [] and list(tmp_path.iterdir()) == []


def test_data_show_bad_data_file_is_one_line(tmp_path, capsys):
    npy = tmp_path / "x.npy"
    np.save(npy, np.zeros(3))
    line = _usage_error(capsys, ["data", "show", "--data", str(npy), "--out", str(tmp_path)])
    assert "x.npy" in line and "expected a dataset archive" in line
    line = _usage_error(capsys, ["data", "show", "--data", str(tmp_path / "none.npz"),
                                 "--out", str(tmp_path)])
    assert "none.npz: no such file" in line
