"""Chapter 7 — the dataset file format, version 2, pinned: a file written before the
dataset module was split still loads, today's writer writes the same header, and every
public name of the dataset lives in one module."""

import base64
import hashlib
import importlib
import json
import zipfile
from pathlib import Path

import numpy as np

from minimanc import world
from minimanc.world import datareader, datawriter, fileformat, generation, scenes

# --------------------------------------------------------------------------- file format v2, pinned
# A two-scene dataset whose arrays are small exact integers (identical on every machine), saved
# with shard_scenes=1. OLD_FILE_V2 is that file as written by the writer before the dataset module
# was split into fileformat / scenes / datawriter / datareader / generation: it must keep loading,
# and today's writer must produce the same header (same members, meta, checksums).

RECIPE = {
    "arms": [
        {"angle": -0.11603336747315302, "lanes": 2,
         "pieces": [[30.0, 0.0], [27.855, 0.0], [33.31, 0.0]]},
        {"angle": 1.645981184202962, "lanes": 1,
         "pieces": [[30.0, 0.0], [71.024, 0.0], [35.282, -0.010683], [80.011, 0.0],
                    [57.613, 0.0], [59.536, 0.0]]},
        {"angle": 3.2406539921364463, "lanes": 2,
         "pieces": [[30.0, 0.0], [80.289, 0.0], [43.245, 0.0]]},
        {"angle": 4.737981566568813, "lanes": 1,
         "pieces": [[30.0, 0.0], [69.655, 0.0], [14.68, -0.009914]]},
    ],
    "ego": {"arm_in": 2, "arm_out": 1, "lane_pick": 0.9340435159562497,
            "start_dist": 107.53413360282693},
    "kind": "intersection", "rotation": -1.4464727375963786,
}
TINY_CONTENT_HASH = "0e52b347e7a49e1bde104b80d4fdcf392cd6bd181e868e1bdda3ac7f94024e3c"
TINY_HEADER_SHA = "5f0597cca1a115a7f88caa959ea19c61f3c8a3280f61aaa91ced045ec1d48f91"
FIELDS_V2 = ("bev", "ego", "controls", "goal", "lane_target", "ado", "ado_valid", "goal_bev")
META_V2 = ("seed", "version", "dt", "raster", "recipes", "tags", "attempts", "scene_index")


def _tiny() -> world.Dataset:
    S, T, H, A, K = 2, 3, 8, 2, 2

    def n(shape, dtype, k):
        return (np.arange(int(np.prod(shape))) * k % 251).astype(dtype).reshape(shape)
    arrays = {
        "bev": n((S, T, H, H, 3), np.uint8, 7), "ego": n((S, T, 3), np.float32, 0.5),
        "controls": n((S, T, 2), np.float32, 0.25), "goal": n((S, T, 3), np.float32, -1.5),
        "lane_target": n((S, T, K, 2), np.float32, 4.0), "ado": n((S, T, A, 5), np.float32, 0.125),
        "ado_valid": n((S, T, A), np.int64, 1) % 2 == 0, "goal_bev": n((S, H, H, 3), np.uint8, 3),
    }
    meta = {"seed": 7, "version": 1, "dt": 0.5, "raster": {
        "draw_crossings": True, "draw_lanes": True, "draw_walkways": True, "ego_length": 4.727,
        "ego_width": 1.907, "lane_width_m": 0.5, "metres_ahead": 40.0, "metres_behind": 10.0,
        "metres_side": 25.0, "size": 8}, "recipes": [RECIPE, RECIPE],
        "tags": [{"kind": "a"}, {"kind": "b"}], "attempts": [1, 2], "scene_index": [0, 1]}
    return world.Dataset(**arrays, maps=[], meta=meta)


def _header(path: Path) -> dict:
    return json.loads(bytes(np.load(path)["header"]).decode())


def test_the_format_constants_are_those_of_version_2():
    assert fileformat.ARRAY_FIELDS == FIELDS_V2 and fileformat.META_KEYS == META_V2
    assert (world.FILE_FORMAT_VERSION, world.FORMAT_VERSION) == (2, 1)
    assert list(fileformat.empty_meta(7, world.RasterConfig(size=8))) == list(META_V2)


def test_a_file_written_before_the_split_still_loads(tmp_path):
    path = tmp_path / "old.npz"
    path.write_bytes(base64.b64decode(OLD_FILE_V2))
    tiny, back = _tiny(), world.load(path)
    assert back.content_hash() == tiny.content_hash() == TINY_CONTENT_HASH
    assert world.file_content_hash(path) == TINY_CONTENT_HASH
    for f in FIELDS_V2:
        np.testing.assert_array_equal(getattr(back, f), getattr(tiny, f))
        assert getattr(back, f).dtype == getattr(tiny, f).dtype
    assert back.meta == tiny.meta == world.read_meta(path)
    assert back.maps[1].kind == "intersection"


def test_the_writer_keeps_the_v2_layout_and_header(tmp_path):
    path = world.save(_tiny(), tmp_path / "tiny.npz", shard_scenes=1)
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    assert names == [f"{f}-{k:05d}.npy" for k in range(2) for f in FIELDS_V2] + ["header.npy"]
    header = _header(path)
    assert sorted(header) == ["format", "meta", "n_scenes", "sha256", "shards", "version"]
    assert (header["format"], header["version"], header["n_scenes"]) == ("minimanc.world", 2, 2)
    assert sorted(header["meta"]) == sorted(META_V2)
    assert [(s["start"], s["stop"]) for s in header["shards"]] == [(0, 1), (1, 2)]
    assert header["shards"][1]["arrays"]["ado_valid"] == {
        "dtype": "|b1", "shape": [1, 3, 2],
        "sha256": hashlib.sha256(_tiny().ado_valid[1:].tobytes()).hexdigest()}
    assert header["sha256"] == TINY_HEADER_SHA
    old = tmp_path / "old.npz"
    old.write_bytes(base64.b64decode(OLD_FILE_V2))
    assert header == _header(old)


def test_every_public_name_of_the_dataset_lives_in_one_module():
    names = [
        "ARRAY_FIELDS", "Dataset", "DatasetFileError", "DatasetWriter", "Estimate",
        "FILE_FORMAT_VERSION", "FLOAT_FIELDS", "FORMAT_VERSION", "LazyMaps", "MAX_ATTEMPTS",
        "META_KEYS", "PER_SCENE_KEYS", "SHARD_BYTES", "append_scenes", "check_arrays_finite",
        "default_shard_scenes", "describe_non_finite", "empty_meta", "estimate",
        "file_content_hash", "first_non_finite", "generate", "generate_file", "generate_scene",
        "generate_splits", "load", "read_meta", "remove_temp_files", "save", "scene_nbytes",
        "temp_files",
    ]
    modules = (fileformat, scenes, datawriter, datareader, generation)
    homes = {n: [m.__name__ for m in modules if n in m.__all__] for n in names}
    assert {n: h for n, h in homes.items() if len(h) != 1} == {}
    for n in ("Dataset", "DatasetWriter", "load", "save", "generate", "generate_file"):
        assert getattr(world, n) is getattr(importlib.import_module(homes[n][0]), n)


OLD_FILE_V2 = (  # base64 of tiny.npz as the pre-split writer wrote it
    "UEsDBC0AAAAIAAAAIQAVirhY//////////8NABQAYmV2LTAwMDAwLm5weQEAEADAAgAAAAAAAFkBAAAAAAAAm+wX6hsQ"
    "ychQxlCtnpJanFykbqWgXlNqqK6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxjoKFmBkrKmjUKtAKuBi"
    "YOcTlVHWMrSwd/MNiU7KLCiva+2ZPGvhivXb9h45fenmg+fvvjJy8IvJqmgbWTq4+4XGJGcVVtS39U6ZvWjlhu37jp65"
    "fOvhi/ffmDgFxOVUdYytHD38w2JTsosqG9r7ps5ZvGrjjv3Hzl65/ejlh+/MXIIS8mq6JtZOngHhcak5xVWNHf3T5i5Z"
    "vWnngePnrt55/OrjDxZuIUkFdT1TG2evwIj4tNyS6qbOCdPnLV2zedfBE+ev3X3y+tNPVh5hKUUNfTNbF++gyIT0vNKa"
    "5q6JM+YvW7tl96GTF67fe/rm8y82XhFpJU0DcztXn+CoxIz8stqW7kkzFyxft3XP4VMXb9x/9vbLqNep4HUAUEsDBC0A"
    "AAAIAAAAIQBpXiaF//////////8NABQAZWdvLTAwMDAwLm5weQEAEACkAAAAAAAAAGAAAAAAAAAAm+wX6hsQychQxlCt"
    "npJanFykbqWgbpNmoq6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxkCkqaNQq0Ae4GKAAHsGhgYgPgDE"
    "DA4MDApA7ADECUDc4AAAUEsDBC0AAAAIAAAAIQB0ncn5//////////8SABQAY29udHJvbHMtMDAwMDAubnB5AQAQAJgA"
    "AAAAAAAAWQAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC"
    "+RqGOgrGOgpGmjoKtQrkAS4GMGiwAxL2DAwOQNwAxAvsAVBLAwQtAAAACAAAACEASjLArP//////////DgAUAGdvYWwt"
    "MDAwMDAubnB5AQAQAKQAAAAAAAAAYgAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SS"
    "ChJ3S8wpTgWKF2ckFqQC+RqGOgrGQKSpo1CrQB7gYgCBhkpnBoYKZ4aGMiBdCqSLgXQRkC4A0vnOAFBLAwQtAAAACAAA"
    "ACEAAH5mhf//////////FQAUAGxhbmVfdGFyZ2V0LTAwMDAwLm5weQEAEACwAAAAAAAAAGwAAAAAAAAAm+wX6hsQychQ"
    "xlCtnpJanFykbqWgbpNmoq6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxjoKRkCkqaNQq0AG4GIAgwYH"
    "IOHIwOAAxA1AvACIDwDxAyBmcGJgEABiBSA2cAIAUEsDBC0AAAAIAAAAIQD4SruN//////////8NABQAYWRvLTAwMDAw"
    "Lm5weQEAEAD4AAAAAAAAAJkAAAAAAAAAnci9CcJQGEbhz06sLC2/7ka4hb8gIppKbJQ0glYmmIQUYiQRGxEyguACjuAI"
    "GcERHMERPOIGvvAU77ktlnNvXZGTnE0Y5dvMDNWM4p6xauI0O2bBfpNmYfTt02CXR/Q8CQ4R32lb7VrtWO03rV70j9Xk"
    "t7FIgRIyEVG48FHgijseKPHEC2+IK1JFHQ0oHLQwgIsZPKzgI3E/UEsDBC0AAAAIAAAAIQAJ+0SF//////////8TABQA"
    "YWRvX3ZhbGlkLTAwMDAwLm5weQEAEACGAAAAAAAAAE0AAAAAAAAAm+wX6hsQychQxlCtnpJanFykbqWgXpNkqK6joJ6W"
    "X1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxjoKRpo6CrUK5AEuRgYQBABQSwMELQAAAAgAAAAhAB9DMTX/////"
    "/////xIAFABnb2FsX2Jldi0wMDAwMC5ucHkBABAAQAEAAAAAAAASAQAAAAAAAJvsF+obEMnIUMZQrZ6SWpxcpG6loF5T"
    "aqiuo6Cell9UUpSYF59flJIKEndLzClOBYoXZyQWpAL5GoY6ChZgZKypo1CrQAbgYmBm4+ThFxKVkJZTVFHX0jUwNrO0"
    "sXdy9fD2CwwJj4pNSE7LzMkvKq2ormtsae/qnTB52sw58xctXbF63cYt23ftPXD42Mkz5y9dvXH73sMnz1+9/fD5209G"
    "FnYuXgFhMUkZeSVVDW09QxNzK1sHZzdPH/+g0IjouMSU9KzcguKyypr6ptaO7r6JU6bPmrtg8bKVa9Zv2rpj976DR46f"
    "Onvh8rWbd+4/evri9buPX77/YmLl4OYTFBGXklVQVtPU0TcytbC2c3RxBwBQSwMELQAAAAgAAAAhALfZ/37/////////"
    "/w0AFABiZXYtMDAwMDEubnB5AQAQAMACAAAAAAAAWQEAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBeU2qorqOgnpZf"
    "VFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGOgoWYGSsqaNQq0Aq4BIQl1PVMbZy9PAPi03JLqpsaO+bOmfxqo07"
    "9h87e+X2o5cfvjNzCUrIq+maWDt5BoTHpeYUVzV29E+bu2T1pp0Hjp+7eufxq48/WLiFJBXU9UxtnL0CI+LTckuqmzon"
    "TJ+3dM3mXQdPnL9298nrTz9ZeYSlFDX0zWxdvIMiE9LzSmuauybOmL9s7Zbdh05euH7v6ZvPv9h4RaSVNA3M7Vx9gqMS"
    "M/LLalu6J81csHzd1j2HT128cf/Z2y8M7HyiMspahhb2br4h0UmZBeV1rT2TZy1csX7b3iOnL9188PzdV0YOfjFZFW0j"
    "Swd3v9CY5KzCivq23imzF63csH3f0TOXbz188f4bE+eo16ngdQBQSwMELQAAAAgAAAAhAFOnRxr//////////w0AFABl"
    "Z28tMDAwMDEubnB5AQAQAKQAAAAAAAAAZAAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBef"
    "X5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGQKSpo1CrQB7gYmCY4MDAsACINwDxASC+AMQPgPgDEDM4MjBwOAIAUEsDBC0A"
    "AAAIAAAAIQDP59FU//////////8SABQAY29udHJvbHMtMDAwMDEubnB5AQAQAJgAAAAAAAAAXQAAAAAAAACb7BfqGxDJ"
    "yFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGOgpGmjoKtQrkAS4GhgP2"
    "DAwPgJjBgYFBAIgVgNjAAQBQSwMELQAAAAgAAAAhAGBBr27//////////w4AFABnb2FsLTAwMDAxLm5weQEAEACkAAAA"
    "AAAAAGMAAAAAAAAAm+wX6hsQychQxlCtnpJanFykbqWgbpNmoq6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvka"
    "hjoKxkCkqaNQq0Ae4GJoyHVmYMhxZmjIAtKZQDodSKcB6RQgnQykE50BUEsDBC0AAAAIAAAAIQBLnhmd//////////8V"
    "ABQAbGFuZV90YXJnZXQtMDAwMDEubnB5AQAQALAAAAAAAAAAbAAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2ai"
    "rqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGOgpGQKSpo1CrQAbgYmBwcGJgCADiBCAuAOIGIO4A4glA"
    "PAOIFwDxCiDeAMQ7nABQSwMELQAAAAgAAAAhAErv89r//////////w0AFABhZG8tMDAwMDEubnB5AQAQAPgAAAAAAAAA"
    "nQAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrG"
    "OgpGOgqmmjoKtQpkAC4GhgIHBoYKIG4A4hYg7gDiHiCeAMRTgHgGEM8B4gVAvASIVwDxGiDeAMRbgHgHEO8B4gNAfASI"
    "TwDxGSC+AMRXgPgGEN8B4gdA/ASIXwDxGwcAUEsDBC0AAAAIAAAAIQAJ+0SF//////////8TABQAYWRvX3ZhbGlkLTAw"
    "MDAxLm5weQEAEACGAAAAAAAAAE0AAAAAAAAAm+wX6hsQychQxlCtnpJanFykbqWgXpNkqK6joJ6WX1RSlJgXn1+UkgoS"
    "d0vMKU4FihdnJBakAvkahjoKxjoKRpo6CrUK5AEuRgYQBABQSwMELQAAAAgAAAAhACk4r0X//////////xIAFABnb2Fs"
    "X2Jldi0wMDAwMS5ucHkBABAAQAEAAAAAAAASAQAAAAAAAJvsF+obEMnIUMZQrZ6SWpxcpG6loF5Taqiuo6Cell9UUpSY"
    "F59flJIKEndLzClOBYoXZyQWpAL5GoY6ChZgZKypo1CrQAbg8vINCA6LjIlPSs3IzissKa+qbWhu6+zpnzR1xux5C5cs"
    "X7V2w+ZtO/fsP3T0xOlzF69cv3X3weNnL9+8//T1BwMzGycPv5CohLScooq6lq6BsZmljb2Tq4e3X2BIeFRsQnJaZk5+"
    "UWlFdV1jS3tX74TJ02bOmb9o6YrV6zZu2b5r74HDx06eOX/p6o3b9x4+ef7q7YfP334ysrBz8QoIi0nKyCupamjrGZqY"
    "W9k6OLt5+vgHhUZExyWmpGflFhSXVdbUN7V2dPdNBABQSwMELQAAAAgAAAAhADP/Vrz//////////woAFABoZWFkZXIu"
    "bnB5AQAQAJsPAAAAAAAAaQUAAAAAAADtVl2PW7cRTV/zKxZ62RTYChwOh+QEfe5bg77kITAMYUgO14K10uLq2pvU8a/I"
    "H87waj/srWK7aftQIAutQI545xzOHB7eX777/u//+OFPX7396t1l02OdLr+9uPz5DVxeXVz2wzRPst8cpqYj/jfZHdXi"
    "x1dyqzb/BnNMV3++unh/8Xv/vn63MpQbmVffXqxutvvtjezr+u4w7drqyiI6i/3ybiXzrDe389EmL+Dqwr+0H9t4yK3J"
    "hpMcZ52WlW2Su02dDsfjdn891s/TGx2rR3wne30eu5Pd6zv56YOwXh82O91fz68sFtbJp/vg3bYtMVizG7GR7hTc3Dxy"
    "Mc6THjfySqWN593aPUWLvtruRxg+Ch+3TS3oaQket/8cs/x+7Ezr9nbh/MKqMN08jPbXu7HmL24NEB0ixhQSAqHz98TG"
    "yjG+3Wo9JXiBC6h9Wfle+LTORI9TxDXCafbSgJ8gYB0DcQbIwTvP8cP88In8CdbOh6f8tPbZnjXGDlzMOIJ5TOBxDaV1"
    "BHya8pownuOEax9cJGT2gDGEiF+4aQP0mR+nYSSicwjWdky2a4qRYs6AX7jryOv4QVUhrGM+bdoxQzCUlycxnWQ93Wy2"
    "+3vOY3J4M98DLNq63dbXi7AYgwtIQEzRBx7iO84yzZu2PS5PuGS1CmA6cFbmyDjE8/qktdV2b6fjqHXeHvbjWE2HWZax"
    "CQjWVr5gGsdEHDHleKrDH1L7Q2r/e6kNhseqhm/P649jk7ZBWMKqI+PAn+X6XowPMLJaSvgwLasl01uDPmHB4LTfLKkf"
    "GmXXlqc4llN3xKlWAQEgST3nKsLEKsA1QseaBX12PYLYD1C1uUBaoYXcGVanbFN79OXpdIHYsJ3K3eafbkdzV3/tYfUR"
    "eC6uchR13rvIvpTcelTXNXXMtQA1DKlxtfpzdSFTF0kpc0OuVjp3n23JPu5Ck4vtjoamBvrmrey27WMOPxf4mENtrhgD"
    "aI6zQztwJQmEEjlE22Lxuec2OLmSEkt16KR1hdqqa6pRznFYCBR9+wz6zTPo4DRmS4U95MwxMSYtHrU3J0Gll2TAyiwe"
    "A5NQ6R4KVqOUFONZ6Lx8cCFQD/t5OuyOn2lCAc+utoAqNavvEqTlFqhxT2xyiLmbBIxJrtGnikiUMoQUsPfWUX+zAA/H"
    "7beha2yUu1idRal3Cto1alDNXEILseSuoRIWSFRIou+pJSEUKz6iOwd92vr1QXafw1YNkexQSwA7uqUzt4oJJLlgteBE"
    "ktlKYA7Shdlqbt2JrmFTa0PgT2JvPt98sKoGB74G4+A6uVLtMNiFUgYPK72rkJPW4ByUgLXUxtTNd0vL1qn4HP/Dzi8u"
    "ZkZ1rfNnqgCRXBLDtaQpUKSmkR1bF5wf8iZnrkYqKN5Rzi4K94imfKrkNcD5E2j9f//glcNIl/Hh9t6M/k2TEKq5eXTm"
    "lLpYlX3MF7xdQAh2ZCqwyw5ijMUoIpVQJTIX41lscFaf/0cmUVuMqna7KIpd4R5MjtRjDD2ZDriTqcQssReVBJ2dM+Oo"
    "LVeuJmRu5zzyd5iE5GKagCiuyrj9HUUuZsLkQmvorRPqzTpa6KCQ2LqTQXyycyudasL/wCRMhy7nbm9DEFtfzEiJAnKR"
    "rGaGtSS2FxYTSUmBAzSKQMMpocUa5Fztv9gkuPtWmjPvtSvKUma01wG7IWvRTlxiSZkaWAVSZUraixkFgThzrkzVf9qg"
    "vsAksBQxG1TrKUEyNXew7jcEj3ZqtUSCYPsn0yaX7ERiD4Xs+mSrvfn0f8ck0nCdnM0DmJO1GREgmD9UZHKSoiu9ETvo"
    "pdfxLy1VzcZUuhGXf7GqsyYBTybhn73B+Pe/AlBLAQItAy0AAAAIAAAAIQAVirhYWQEAAMACAAANAAAAAAAAAAAAAACA"
    "AQAAAABiZXYtMDAwMDAubnB5UEsBAi0DLQAAAAgAAAAhAGleJoVgAAAApAAAAA0AAAAAAAAAAAAAAIABmAEAAGVnby0w"
    "MDAwMC5ucHlQSwECLQMtAAAACAAAACEAdJ3J+VkAAACYAAAAEgAAAAAAAAAAAAAAgAE3AgAAY29udHJvbHMtMDAwMDAu"
    "bnB5UEsBAi0DLQAAAAgAAAAhAEoywKxiAAAApAAAAA4AAAAAAAAAAAAAAIAB1AIAAGdvYWwtMDAwMDAubnB5UEsBAi0D"
    "LQAAAAgAAAAhAAB+ZoVsAAAAsAAAABUAAAAAAAAAAAAAAIABdgMAAGxhbmVfdGFyZ2V0LTAwMDAwLm5weVBLAQItAy0A"
    "AAAIAAAAIQD4SruNmQAAAPgAAAANAAAAAAAAAAAAAACAASkEAABhZG8tMDAwMDAubnB5UEsBAi0DLQAAAAgAAAAhAAn7"
    "RIVNAAAAhgAAABMAAAAAAAAAAAAAAIABAQUAAGFkb192YWxpZC0wMDAwMC5ucHlQSwECLQMtAAAACAAAACEAH0MxNRIB"
    "AABAAQAAEgAAAAAAAAAAAAAAgAGTBQAAZ29hbF9iZXYtMDAwMDAubnB5UEsBAi0DLQAAAAgAAAAhALfZ/35ZAQAAwAIA"
    "AA0AAAAAAAAAAAAAAIAB6QYAAGJldi0wMDAwMS5ucHlQSwECLQMtAAAACAAAACEAU6dHGmQAAACkAAAADQAAAAAAAAAA"
    "AAAAgAGBCAAAZWdvLTAwMDAxLm5weVBLAQItAy0AAAAIAAAAIQDP59FUXQAAAJgAAAASAAAAAAAAAAAAAACAASQJAABj"
    "b250cm9scy0wMDAwMS5ucHlQSwECLQMtAAAACAAAACEAYEGvbmMAAACkAAAADgAAAAAAAAAAAAAAgAHFCQAAZ29hbC0w"
    "MDAwMS5ucHlQSwECLQMtAAAACAAAACEAS54ZnWwAAACwAAAAFQAAAAAAAAAAAAAAgAFoCgAAbGFuZV90YXJnZXQtMDAw"
    "MDEubnB5UEsBAi0DLQAAAAgAAAAhAErv89qdAAAA+AAAAA0AAAAAAAAAAAAAAIABGwsAAGFkby0wMDAwMS5ucHlQSwEC"
    "LQMtAAAACAAAACEACftEhU0AAACGAAAAEwAAAAAAAAAAAAAAgAH3CwAAYWRvX3ZhbGlkLTAwMDAxLm5weVBLAQItAy0A"
    "AAAIAAAAIQApOK9FEgEAAEABAAASAAAAAAAAAAAAAACAAYkMAABnb2FsX2Jldi0wMDAwMS5ucHlQSwECLQMtAAAACAAA"
    "ACEAM/9WvGkFAACbDwAACgAAAAAAAAAAAAAAgAHfDQAAaGVhZGVyLm5weVBLBQYAAAAAEQARABoEAACEEwAAAAA="
)

