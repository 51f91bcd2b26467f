"""RIR banks: multichannel room impulse responses grouped into ordered trajectories.

Every kind of bank (TAU-SRIR DB as distributed, SOFA ``SingleRoomSRIR`` files, the
toolkit's own HDF5 format, in-memory banks) has the same interface, :class:`Bank`::

    bank = open_bank("path/to/TAU-SRIR_DB", format="foa")
    traj = bank.trajectories("tc352")[0]
    rirs = bank.read("tc352", traj.id, [0, 5, 10])     # float32 [3, 4, L]
    traj.positions[[0, 5, 10]]                            # (az, el, dist) [3, 3]

Import order inside the package (each module imports only those above it)::

    base            Bank, Trajectory, MemoryBank, check_format, check_rate
    _h5, paths      HDF5 reading helpers; walks along trajectories
    plausible       whether a room's positions and RIR shapes can be trusted
    tau, sofa, native   one module per file format
    kinds           open_bank: guess the kind of a path and open it
    build           simulated banks (the shoebox simulator), the demo bank
    scenes          how a dataset uses a bank: resolve, check, split rooms, per-process cache

See docs/banks.md for the file layouts and rir_banks/README.md for where banks come from.
"""
from ..errors import BankError
from .base import Bank, MemoryBank, Trajectory, azimuth_coverage, check_format
from .kinds import open_bank
from .paths import bank_path_positions, sample_bank_path, sample_bank_point

__all__ = [
    "Bank",
    "BankError",
    "MemoryBank",
    "Trajectory",
    "azimuth_coverage",
    "bank_path_positions",
    "check_format",
    "open_bank",
    "sample_bank_path",
    "sample_bank_point",
]
