"""The report's figures are encoded once, on the job's threads, into the same data: URIs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from pose_uncertainty.present.report import _data_uri, _encode_all, _pngs


def _png(path: Path, seed: int) -> str:
    rgb = np.random.default_rng(seed).integers(0, 256, size=(40, 60, 3), dtype=np.uint8)
    Image.fromarray(rgb).save(path)
    return str(path)


def test_pngs_are_found_anywhere_in_the_manifest():
    tree = {"sets": [{"figures": {"a": "x/a.png"}, "runs": [{"figures": ["x/b.PNG", "x/c.svg"]}]}], "n": 3}
    assert _pngs(tree, {"more": ("x/a.png",)}) == ["x/a.png", "x/b.PNG"]


def test_encoded_on_threads_gives_the_uris_encoded_one_by_one(tmp_path, monkeypatch):
    paths = [_png(tmp_path / f"f{i}.png", i) for i in range(6)]
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    encoded = _encode_all([*paths, str(tmp_path / "missing.png")])
    assert sorted(encoded) == sorted(paths)  # a missing file is left to the template's own error
    for p in paths:
        assert _data_uri(p, encoded) == _data_uri(p)
        assert _data_uri(p).startswith("data:image/webp;base64,")
