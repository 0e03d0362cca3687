"""Chapter 7 — `minimanc data generate` and `minimanc data show`."""

import numpy as np
import pytest
from PIL import Image

from minimanc import world
from minimanc.cli import main


def test_data_generate_and_show(tmp_path, capsys):
    out = tmp_path / "data"
    assert main(["data", "generate", "--scenes", "3", "--seed", "4", "--out", str(out),
                 "--workers", "1", "--quiet"]) == 0
    path = out / "world_3x4.npz"
    ds = world.load(path)
    assert len(ds) == 3 and ds.meta["seed"] == 4
    text = capsys.readouterr().out
    assert "generated 3 scenes" in text and ds.content_hash()[:16] in text
    show = tmp_path / "show"
    assert main(["data", "show", "--data", str(path), "--out", str(show), "--scene", "1"]) == 0
    gallery = Image.open(show / "gallery.png")
    assert gallery.size[0] > 300
    gif = Image.open(show / "scene.gif")
    assert gif.n_frames == world.T_STEPS
    frame = np.asarray(gif.convert("RGB"))
    assert frame.shape[0] == 4 * 64  # frames are upscaled 4x
    assert (show / "scene_map.png").exists()


def test_data_show_rejects_a_bad_scene(tmp_path):
    out = tmp_path / "data"
    main(["data", "generate", "--scenes", "1", "--out", str(out), "--workers", "1", "--quiet"])
    with pytest.raises(SystemExit, match="--scene"):
        main(["data", "show", "--data", str(out / "world_1x0.npz"), "--out", str(tmp_path),
              "--scene", "5"])
