"""docs/tutorial.ipynb runs as written: every code cell in order, in one namespace, as a
kernel would (without a notebook server: IPython's display objects are real, and what
the notebook displays is recorded). The PyTorch cell runs when torch is installed."""
from __future__ import annotations

import importlib.util
import json
import tempfile

import numpy as np
import pytest
import soundfile as sf

from support import REPO

NOTEBOOK = REPO / "docs" / "tutorial.ipynb"


def code_cells() -> list[str]:
    nb = json.loads(NOTEBOOK.read_text(encoding="utf-8"))
    assert nb["nbformat"] == 4
    return ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]


@pytest.mark.slow
def test_the_tutorial_notebook_runs(tmp_path, monkeypatch):
    display = pytest.importorskip("IPython.display")
    shown = []
    monkeypatch.setattr(display, "display", lambda *objs, **_: shown.extend(objs))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the notebook's folder, removed with tmp_path
    ns: dict = {"__name__": "__main__"}
    cells = code_cells()
    torch_cells = [c for c in cells if "from torch" in c or "import torch" in c]
    assert torch_cells, "the notebook reads the dataset with torch"
    for cell in cells:
        if cell in torch_cells and importlib.util.find_spec("torch") is None:
            continue
        exec(compile(cell, str(NOTEBOOK), "exec"), ns)
    scene = ns["scene"]
    assert scene.query and scene.audio.shape[1] == 4 * scene.fs
    picture, mono, stereo = shown
    assert isinstance(picture, display.Image) and picture.data[:8] == b"\x89PNG\r\n\x1a\n"
    for played, channels in ((mono, 1), (stereo, 2)):  # the WAV the player gets: the scene's length and rate
        info = sf.info(__import__("io").BytesIO(played.data))
        assert (info.samplerate, info.channels, info.frames) == (scene.fs, channels, scene.audio.shape[1])
    if "batch" in ns:
        assert tuple(ns["batch"]["audio"].shape) == (4, 4, 4 * scene.fs) and len(ns["batch"]["query"]) == 4
        assert np.isfinite(ns["batch"]["gaussian"].numpy()).all()
