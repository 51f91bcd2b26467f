"""Opening a bank of any kind: TAU-SRIR DB folders, SOFA files, the toolkit's own HDF5
banks, guessed from the path."""
from __future__ import annotations

import os
from pathlib import Path

import h5py

from ..core.files import check_input
from ..core.h5str import as_str
from ..errors import BankError, broken_link
from .base import Bank, check_format
from .native import NativeBank, is_native_bank
from .sofa import SofaBank
from .tau import TauBank, is_tau_folder


def open_bank(path_or_dir, kind: str = "auto", format: str | None = None, **options) -> Bank:
    """Open a bank of any kind.

    kind: ``auto`` (guess from the path), ``tau`` (a TAU-SRIR DB directory as
    distributed: rirdata.mat, measinfo.mat, rirs_NN_<room>.mat), ``sofa`` (one
    ``.sofa`` file, a directory of them, or a list of files; one room per file),
    ``native`` (the toolkit's HDF5 bank, see docs/banks.md). ``format``: the array
    format to read where a source holds several (TAU: ``foa`` or ``mic``/``tetra``).
    """
    if isinstance(path_or_dir, (list, tuple)):
        paths = [Path(p) for p in path_or_dir]
        for p in paths:
            if not p.exists():
                raise BankError(f"RIR bank file {p} {broken_link(str(p)) or 'not found'}")
            _regular(p)
        return SofaBank(paths, format=format, **options)
    p = Path(os.path.expanduser(str(path_or_dir)))
    if not p.exists():
        raise BankError(f"RIR bank {p} {broken_link(str(p)) or 'not found'}; give a TAU-SRIR DB directory, a .sofa "
                        f"file or directory, or a bank .h5 file")
    _regular(p)
    if kind == "auto":
        kind = _guess_kind(p)
    if kind == "tau":
        return TauBank(p, format=format or "foa", **options)
    if kind == "sofa":
        return SofaBank(p, format=format, **options)
    if kind == "native":
        bank = NativeBank(p, **options)
        if format is not None and check_format(format) != bank.format:
            want = check_format(format)
            raise BankError(f"{p}: the bank holds {bank.format} RIRs, not {want}; use a {want} bank "
                            f"(or scene.format = \"{bank.format}\")")
        return bank
    raise BankError(f"{p}: unknown bank kind {kind!r}; expected auto, tau, sofa or native")


def _regular(p: Path) -> None:
    """A bank is a folder or a regular file: reading a pipe would wait for a writer forever."""
    if not p.is_dir():
        check_input(p, BankError, "give the bank file itself")


def _guess_kind(p: Path) -> str:
    if p.is_dir():
        if is_tau_folder(p):
            return "tau"
        if any(p.glob("*.sofa")):
            return "sofa"
        if is_tau_folder(p / "TAU-SRIR_DB"):
            raise BankError(f"{p}: this holds TAU-SRIR_DB/; point at {p / 'TAU-SRIR_DB'} instead")
        raise BankError(f"{p}: not an RIR bank directory (no rirdata.mat of the TAU-SRIR DB, no .sofa files)")
    suffix = p.suffix.lower()
    if suffix == ".sofa":
        return "sofa"
    if suffix == ".mat":
        raise BankError(f"{p}: give the TAU-SRIR DB directory (with rirdata.mat and measinfo.mat), not one .mat file")
    if is_native_bank(p):
        return "native"
    if _is_sofa(p):
        return "sofa"
    raise BankError(f"{p}: not an RIR bank (neither a tsel bank .h5 nor a SOFA file)")


def _is_sofa(p: Path) -> bool:
    try:
        with h5py.File(p, "r") as f:
            return as_str(f.attrs.get("Conventions")) == "SOFA"
    except OSError:
        return False
