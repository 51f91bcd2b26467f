"""Room impulse responses behind one interface.

``simulate_rirs(room, array, points, fs, method, seed)`` returns the RIRs from each
room-frame point to each channel of the array, as a :class:`RirSet`. Sample 0 of every
RIR is the emission time, so the direct path of a source at distance r arrives at
r / c · fs samples (no filter latency left in).

Methods: ``pyroomacoustics`` (the library's default path, as users write it: absorption
and max order from ``inverse_sabine``, ``compute_rir``), and the project's own
``ism`` / ``hybrid`` (see shoebox.py, docs/acoustics.md).

Import order: ``base`` (RirSet), then ``metrics``, ``highpass``, ``ism``, ``late``, then
the methods ``shoebox`` and ``pyroom``, then ``simulate`` (the dispatcher).
"""
from ..core.geometry import SOUND_SPEED
from .base import RirSet
from .simulate import RIR_METHODS, simulate_rirs

__all__ = ["RIR_METHODS", "RirSet", "SOUND_SPEED", "simulate_rirs"]
