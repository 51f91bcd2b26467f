"""docs/design.md's layers hold in the code: every import (at the top of a module or
inside a function) points to the same or a lower layer, the read side reads through the
store only, and there is no import cycle."""
import ast
import os
import re

import pytest
from support import REPO

ROOT = str(REPO)
PKG = os.path.join(ROOT, "tsel_data")


def _layers() -> dict[str, int]:
    with open(os.path.join(ROOT, "docs", "design.md"), encoding="utf-8") as f:
        block = re.search(r"```layers\n(.*?)```", f.read(), re.S).group(1)
    out = {}
    for line in block.strip().splitlines():
        head, names = line.split(":", 1)
        for name in names.split():
            out[name] = int(head.split()[0])
    return out


def _modules() -> dict[str, str]:
    """Dotted module name -> file, for every module of the package."""
    out = {}
    for dirpath, _, files in os.walk(PKG):
        for f in files:
            if f.endswith(".py"):
                rel = os.path.relpath(os.path.join(dirpath, f), ROOT)[:-3].replace(os.sep, ".")
                out[rel.removesuffix(".__init__") if rel.endswith(".__init__") else rel] = os.path.join(dirpath, f)
    return out


def _imports(name: str, path: str, modules) -> set[str]:
    """The package modules ``name`` imports, anywhere in the file."""
    tree = ast.parse(open(path, encoding="utf-8").read())
    package = name if path.endswith("__init__.py") else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def _unit(name: str) -> str:
    """The layer entry a module belongs to: its first component under tsel_data."""
    parts = name.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


MODULES = _modules()
GRAPH = {m: _imports(m, p, MODULES) for m, p in MODULES.items()}
LAYERS = _layers()


def test_every_module_has_a_layer():
    missing = sorted({_unit(m) for m in MODULES} - set(LAYERS))
    assert not missing, f"add these to the layers block of docs/design.md: {missing}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_point_down(module):
    mine = LAYERS[_unit(module)]
    up = [t for t in GRAPH[module] if LAYERS[_unit(t)] > mine]
    assert not up, f"{module} (layer {mine}) imports higher layers: {up}"


def _edges():
    """(importer, imported) module pairs between different layer units."""
    return [(m, t) for m, ts in GRAPH.items() for t in ts if _unit(m) != _unit(t)]


def test_packages_of_one_layer_do_not_import_each_other():
    same = sorted(f"{m} -> {t}" for m, t in _edges() if LAYERS[_unit(m)] == LAYERS[_unit(t)])
    assert not same, f"packages of one layer import each other (move one down, or the shared part): {same}"


def test_read_side_reads_through_the_store_only():
    read_side = {"tools", "export"}
    allowed = {u for u, layer in LAYERS.items() if layer <= LAYERS["acoustics"]} | {"store", "formats"} | read_side
    for m, t in _edges():
        if _unit(m) in read_side:
            assert _unit(t) in allowed, f"{m} is read-side but imports {t}"


def _imports_h5py(path: str) -> bool:
    for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
            [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
        if any(n == "h5py" or n.startswith("h5py.") for n in names):
            return True
    return False


def test_h5py_is_imported_only_by_the_file_format_packages():
    allowed = ("tsel_data.store", "tsel_data.banks", "tsel_data.formats")
    users = sorted(m for m, p in MODULES.items() if _imports_h5py(p))
    assert "tsel_data.store.reader" in users  # the check sees them
    stray = [m for m in users if not m.startswith(allowed) and m != "tsel_data.acoustics.sofa"]
    assert not stray, f"h5py imported outside store/, banks/, formats/ and acoustics/sofa.py: {stray}"


def test_the_top_level_reads_as_the_pipeline():
    entries = sorted(e for e in os.listdir(PKG) if e != "__pycache__")
    assert len(entries) <= 20, entries
    for e in entries:
        assert e.endswith(".py") or os.path.isfile(os.path.join(PKG, e, "__init__.py")), f"{e} is not a package"


def test_no_import_cycle():
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in GRAPH[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in GRAPH:
        if v not in index:
            visit(v)
    assert not cycles, cycles


def test_the_checker_sees_imports_inside_functions():
    assert "tsel_data.corpus.demo" in GRAPH["tsel_data.plan.catalog"]  # imported inside resolve_corpus_dir
    assert "tsel_data.store.reader" in GRAPH["tsel_data"]  # the root's lazy open_dataset


def test_the_short_public_paths_are_the_modules_themselves():
    import importlib
    import importlib.util

    from tsel_data import PUBLIC_MODULES

    assert {"torch", "streaming", "evaluate", "labels", "onthefly", "features"} <= set(PUBLIC_MODULES)
    for short, real in PUBLIC_MODULES.items():
        assert f"tsel_data.{real}" in MODULES, real
        if short == "torch" and importlib.util.find_spec("torch") is None:
            continue  # the module refuses to load without PyTorch; its path is checked above
        assert importlib.import_module(f"tsel_data.{short}") is importlib.import_module(f"tsel_data.{real}")
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("tsel_data.no_such_module")
