"""Each optional extra of pyproject.toml declares what its packages need to import.

``pip install 'tsel-data[lhotse]'`` once installed a lhotse that could not be imported:
lhotse 1.33 imports ``urllib3`` at top level without declaring it. This test resolves an
extra's requirements (with tsel-data's own) transitively through the installed
distributions' metadata, then imports the extra's packages in a fresh interpreter in
which every other installed top-level module is hidden: what a clean environment with
only that extra would hold. An extra whose packages are not all installed here is skipped.
"""
from __future__ import annotations

import importlib.metadata as md
import subprocess
import sys
import tomllib

import pytest
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from support import REPO

PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
EXTRAS = PROJECT["optional-dependencies"]
NOT_MODULES = {"tests", "test", "docs", "doc", "examples", "benchmarks", "scripts"}  # stray top-level folders


def _active(req: Requirement, extras) -> bool:
    if req.marker is None:
        return True
    return any(req.marker.evaluate({**default_environment(), "extra": e}) for e in (*extras, ""))


def _dist(name: str):
    try:
        return md.distribution(name)
    except md.PackageNotFoundError:
        return None


def closure(requirements) -> set[str]:
    """The canonical names of the installed distributions ``requirements`` (strings) need,
    transitively, extras and environment markers evaluated; a requirement not installed
    here is left out (the import then tells)."""
    seen: set[tuple[str, frozenset]] = set()
    todo = [Requirement(r) for r in requirements]
    while todo:
        req = todo.pop()
        key = (canonicalize_name(req.name), frozenset(req.extras))
        if key in seen:
            continue
        seen.add(key)
        dist = _dist(req.name)
        if dist is not None:
            todo += [r for r in map(Requirement, dist.requires or []) if _active(r, req.extras)]
    return {name for name, _ in seen if _dist(name) is not None}


def top_level(dist) -> set[str]:
    """What ``dist`` installed at the top of site-packages (packages, modules, its .dist-info,
    its bundled libraries), from its RECORD."""
    return {f.parts[0] for f in dist.files or () if f.parts and f.parts[0] not in ("..", "__pycache__")
            and not f.parts[0].endswith(".pth")}


def modules_of(req: Requirement) -> list[str]:
    """The module a requirement is imported as (``pytest-xdist``: xdist), and those of the
    distributions its extras add (``dask[distributed]``: dask, distributed)."""
    out = []
    dists = [_dist(req.name)] + [_dist(r.name) for r in map(Requirement, _dist(req.name).requires or [])
                                 if req.extras and r.marker is not None and _active(r, req.extras)
                                 and not _active(r, ())]
    for dist in filter(None, dists):
        names = sorted(n.removesuffix(".py") for n in top_level(dist) if "." not in n.removesuffix(".py"))
        names = [n for n in names if n.isidentifier() and not n.startswith("_") and n not in NOT_MODULES]
        own = canonicalize_name(dist.metadata["Name"]).replace("-", "_")
        out += [own] if own in names else names
    return out


# A fresh interpreter without site-packages (-S, -E), whose only path beyond the standard
# library is a folder of links to what the extra's closure installed: a clean environment
# with that extra alone. Optional imports (find_spec, try/except ImportError) see the rest
# as absent, as they would there.
PROBE = """
import importlib, sys
sys.path.insert(0, sys.argv[1])
for m in sys.argv[2:]:
    importlib.import_module(m)
"""


@pytest.mark.slow
@pytest.mark.parametrize("extra", sorted(EXTRAS))
def test_an_extra_declares_what_its_packages_import(extra, tmp_path):
    reqs = [Requirement(r) for r in EXTRAS[extra]]
    absent = [r.name for r in reqs if _dist(r.name) is None]
    if absent:
        pytest.skip(f"[{extra}]: {', '.join(absent)} not installed here")
    site = tmp_path / "site-packages"
    site.mkdir()
    for name in sorted(closure([*PROJECT["dependencies"], *EXTRAS[extra]])):
        dist = _dist(name)
        for top in top_level(dist):
            source = dist.locate_file(top)
            if source.exists() and not (site / top).exists():
                (site / top).symlink_to(source)
    wanted = [m for r in reqs for m in modules_of(r)]
    assert wanted, f"[{extra}]: no module found for {[r.name for r in reqs]}"
    r = subprocess.run([sys.executable, "-S", "-E", "-c", PROBE, str(site), *wanted], capture_output=True, text=True,
                       cwd=tmp_path, timeout=600)
    last = r.stderr.strip().splitlines()[-1:] or [""]
    assert r.returncode == 0, (f"[{extra}] = {EXTRAS[extra]}: importing {', '.join(wanted)} with only what the "
                               f"extra requires installed fails: {last[0]}")


def test_the_closure_follows_requirements_and_their_extras():
    if _dist("lhotse") and _dist("torch"):  # an extra of the project: installed here or not
        got = closure(["lhotse"])
        assert {"lhotse", "torch", "numpy", "soundfile"} <= got and "urllib3" not in got  # lhotse declares no urllib3
    assert {"numpy", "soundfile"} <= closure(["soundfile"]) and "soundfile" not in closure(["numpy"])
    if _dist("dask") and _dist("distributed"):
        assert "distributed" in closure(["dask[distributed]"]) and "distributed" not in closure(["dask"])
        assert modules_of(Requirement("dask[distributed]")) == ["dask", "distributed"]
    if _dist("pytest-xdist"):
        assert modules_of(Requirement("pytest-xdist")) == ["xdist"]
