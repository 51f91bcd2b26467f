"""Tiny RIR banks in the exact on-disk layouts, generated at test time.

- :func:`make_tau_db`: a TAU-SRIR DB directory as distributed — rirdata.mat and
  measinfo.mat (MATLAB v5, scipy.io.savemat) and rirs_NN_<room>.mat (MATLAB v7.3:
  HDF5 with a 512-byte user block, struct array ``rirs`` [trajectory x height] stored
  as a group whose field datasets hold object references with reversed dimensions,
  each pointing to a [nDOA, 4, L] dataset under ``#refs#``).
- :func:`make_sofa`: a SOFA SingleRoomSRIR file written with netCDF4, either the way
  SpatialScaper's prepare_rirs.py writes ``<room>_{foa,mic}.sofa`` or a generic one
  (spherical SourcePosition relative to a listener with a view direction).
"""
from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import scipy.io

from tsel_data.core.geometry import sph_to_cart


def ring_doas(n: int, el_deg: float, az0: float = 0.0, step: float | None = None) -> np.ndarray:
    """Unit vectors [n, 3] along a ring (x front, y left, z up), azimuth az0 + k·step."""
    step = 360.0 / n if step is None else step
    return sph_to_cart(az0 + step * np.arange(n), el_deg, 1.0)


LINEAR_ROOMS = {"sa203", "sc203", "se203", "tb103"}  # the rest of the TAU-SRIR DB is circular
MIC_HEIGHT = 1.2


def make_tau_db(root, rooms=(("bomb_shelter", 1), ("se203", 8)), n_traj=2, heights=(0.8, 1.2, 1.6),
                n_doa=24, L=48, fs=24000, dists=(1.5, 2.5), empty=((1, 2),), seed=0, doas=None):
    """Write a TAU-layout directory; returns {room: {(t, h): {"mic": [n,4,L], "foa": ..., "doa": [n,3],
    "dist": [n]}}}.

    As measinfo.mat describes the DB: heights are metres above the floor, the array is at
    micPosition [0, 0, 1.2]. Circular rooms: group t is a ring of horizontal radius
    dists[t], ``distances`` = [1 x nTraj]. Linear rooms (LINEAR_ROOMS): group t is a line
    parallel to y at x = ±dists[t] (alternating sides, from +y to -y), ``distances`` =
    start/end points [2 x 3 x nTraj]. ``doas`` overrides doa_xyz of some (room, t, h).
    """
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    truth, room_recs, meas_recs = {}, [], []
    for name, number in rooms:
        linear = name in LINEAR_ROOMS
        rirs_rec = np.empty((n_traj, len(heights)), dtype=[("doa_xyz", object)])
        counts = np.zeros((n_traj, len(heights)))
        truth[name] = {}
        for t in range(n_traj):
            for h, height in enumerate(heights):
                if (t, h) in empty:
                    rirs_rec[t, h]["doa_xyz"] = np.zeros((0, 0))
                    continue
                z = height - MIC_HEIGHT
                if doas and (name, t, h) in doas:
                    doa = doas[(name, t, h)]
                    dist = np.full(len(doa), np.nan)
                elif linear:
                    x = dists[t] * (1 if t % 2 == 0 else -1)
                    pts = np.stack([np.full(n_doa, x), np.linspace(3.0, -3.0, n_doa), np.full(n_doa, z)], -1)
                    dist = np.linalg.norm(pts, axis=1)
                    doa = pts / dist[:, None]
                else:
                    el = np.degrees(np.arctan2(z, dists[t]))
                    doa = ring_doas(n_doa, el, az0=7.0 * t)
                    dist = np.full(n_doa, np.hypot(dists[t], z))
                rirs_rec[t, h]["doa_xyz"] = doa
                counts[t, h] = len(doa)
                truth[name][(t, h)] = {
                    "doa": doa, "dist": dist,
                    "mic": rng.standard_normal((len(doa), 4, L)).astype(np.float32),
                    "foa": rng.standard_normal((len(doa), 4, L)).astype(np.float32),
                }
        if linear:
            xs = [dists[t] * (1 if t % 2 == 0 else -1) for t in range(n_traj)]
            distances = np.array([[xs, [3.0] * n_traj, [0.0] * n_traj], [xs, [-3.0] * n_traj, [0.0] * n_traj]])
        else:
            distances = np.array([list(dists[:n_traj])])
        room_recs.append((name, 2019, rirs_rec, counts))
        groups = np.array([[f"group{t}" for t in range(n_traj)]], dtype=object)
        meas_recs.append((name, groups, np.array([[8.0, 6.0, 3.0]]), distances, np.array([list(heights)]),
                          np.array([[0.0, 0.0, MIC_HEIGHT]]), "linear" if linear else "circular"))
        _write_v73(root / f"rirs_{number:02d}_{name}.mat", truth[name], n_traj, len(heights), L)

    room_arr = np.empty((len(rooms), 1), dtype=[("name", object), ("year", object), ("rirs", object), ("nRirs", object)])
    for i, rec in enumerate(room_recs):
        room_arr[i, 0] = rec
    rirdata = {"fs": np.array([[fs]]), "room": room_arr, "tetra_mic_radius_m": np.array([[0.042]])}
    scipy.io.savemat(root / "rirdata.mat", {"rirdata": rirdata}, format="5")
    keys = ("room", "trajectories", "dimensions", "distances", "heights", "micPosition", "trajectoryType")
    meas_arr = np.empty((len(rooms), 1), dtype=[(k, object) for k in keys])
    for i, rec in enumerate(meas_recs):
        meas_arr[i, 0] = rec
    scipy.io.savemat(root / "measinfo.mat", {"measinfo": meas_arr}, format="5")
    return truth


def _write_v73(path, room_truth, n_traj, n_height, L):
    """MATLAB v7.3 layout of ``rirs = struct array [n_traj x n_height]`` with fields mic, foa."""
    with h5py.File(path, "w", userblock_size=512) as f:
        refs_group = f.create_group("#refs#")
        g = f.create_group("rirs")
        g.attrs["MATLAB_class"] = np.bytes_("struct")
        vlen = h5py.vlen_dtype(np.dtype("S1"))
        fields = np.empty(2, dtype=object)
        fields[0], fields[1] = np.array(list(b"mic"), dtype="S1"), np.array([b"f", b"o", b"a"], dtype="S1")
        fields[0] = np.array([b"m", b"i", b"c"], dtype="S1")
        g.attrs.create("MATLAB_fields", fields, dtype=vlen)
        counter = 0
        for field in ("mic", "foa"):
            refs = np.empty((n_height, n_traj), dtype=h5py.ref_dtype)  # reversed dims
            for t in range(n_traj):
                for h in range(n_height):
                    name = f"r{counter}"
                    counter += 1
                    if (t, h) in room_truth:
                        ds = refs_group.create_dataset(name, data=room_truth[(t, h)][field].astype(np.float64))
                        ds.attrs["MATLAB_class"] = np.bytes_("double")
                    else:
                        ds = refs_group.create_dataset(name, data=np.array([0, 0], dtype=np.uint64))
                        ds.attrs["MATLAB_class"] = np.bytes_("double")
                        ds.attrs["MATLAB_empty"] = np.uint8(1)
                    refs[h, t] = ds.ref
            g.create_dataset(field, data=refs, dtype=h5py.ref_dtype)
    # MATLAB's 128-byte text header at the start of the user block
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: test HDF5 schema 1.00 .".ljust(116) + b"\x00" * 8 + b"\x00\x02IM")


def make_sofa(path, rirs, positions, fs=24000, style="spatialscaper", listener=(4.0, 3.0, 1.2),
              listener_view=None, room="testroom", listener_name="foa", with_source=True):
    """Write a SingleRoomSRIR SOFA file. positions: array-relative cartesian [M, 3] (m).

    style="spatialscaper": SourcePosition as given (already array-relative), ListenerPosition
    = the array's room position, as prepare_rirs.py writes. style="generic": SourcePosition
    in the room frame (listener + R·p, R rotating the array's x to ``listener_view``),
    spherical (deg, deg, m), as the SOFA standard intends.
    """
    from netCDF4 import Dataset

    rirs = np.asarray(rirs, dtype=np.float64)
    M, R, N = rirs.shape
    root = Dataset(str(path), "w", format="NETCDF4")
    root.Conventions = "SOFA"
    root.Version = "2.1"
    root.SOFAConventions = "SingleRoomSRIR"
    root.DataType = "FIR"
    root.RoomType = "shoebox"
    root.ListenerShortName = listener_name
    root.RoomShortName = room
    if style == "spatialscaper":
        root.Organization = "Music and Audio Research Lab - NYU"
        root.DatabaseName = "TAU-SRIR-DB-SOFA"
        root.Comment = f"SOFA conversion of {room} from TAU-SRIR-DB"
    else:
        root.Organization = "tests"
        root.DatabaseName = "tests"
    for dim, n in (("M", M), ("N", N), ("R", R), ("E", 1), ("I", 1), ("C", 3)):
        root.createDimension(dim, n)
    lp = root.createVariable("ListenerPosition", "f8", ("M", "C"))
    lp.Units, lp.Type = "metre", "cartesian"
    lp[:] = np.tile(listener, (M, 1))
    sp = root.createVariable("SourcePosition", "f8", ("M", "C")) if with_source else None
    pos = np.asarray(positions, dtype=np.float64)
    if style == "spatialscaper":
        if with_source:
            sp.Units, sp.Type = "metre", "cartesian"
            sp[:] = pos
        lv = root.createVariable("ListenerView", "f8", ("I", "C"))
        lv.Units, lv.Type = "metre", "cartesian"
        lv[:] = np.array([[1.0, 0.0, 0.0]])
    else:
        view = np.asarray(listener_view if listener_view is not None else (1.0, 0.0, 0.0), dtype=np.float64)
        yaw = np.arctan2(view[1], view[0])
        rot = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1.0]])
        room_pos = np.asarray(listener) + pos @ rot.T
        if with_source:
            d = room_pos  # spherical about the room origin, per SOFA: (az, el, r) of the point
            az = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
            el = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
            sp.Units, sp.Type = "degree, degree, metre", "spherical"
            sp[:] = np.stack([az, el, np.linalg.norm(d, axis=1)], axis=-1)
        lv = root.createVariable("ListenerView", "f8", ("I", "C"))
        lv.Units, lv.Type = "metre", "cartesian"
        lv[:] = view[None, :]
    sr = root.createVariable("Data.SamplingRate", "f8", ("I",))
    sr.Units = "hertz"
    sr[:] = fs
    ir = root.createVariable("Data.IR", "f8", ("M", "R", "N"))
    ir[:] = rirs
    root.close()
    return Path(path)


def make_native_bank(path, rooms=("roomA", "roomB"), fmt="mic4", fs=24000, n=36, dist=1.5, dims=(7.5, 6.0, 3.0),
                     centre=(3.5, 3.0, 1.2), yaw=0.0, side=0.11):
    """A plausible toolkit bank: per room one closed ring of ``n`` positions ``dist`` m
    around an array at ``centre`` (room frame) of a ``dims`` room, random 64-tap RIRs,
    the room info ``tsel bank build`` writes (dims, array centre, yaw and side). Damage it
    afterwards with h5py to make implausible ones."""
    from tsel_data.banks import MemoryBank, Trajectory
    from tsel_data.banks.native import write_bank
    from tsel_data.receivers import receiver

    rng = np.random.default_rng(0)
    az = np.arange(n) * 360.0 / n - 180.0
    pos = np.stack([az, np.zeros(n), np.full(n, dist)], axis=1)
    channels = len(receiver(fmt).channel_names)
    items = {r: [(Trajectory(r, "0", "circular", pos, closed=True),
                  (0.1 * rng.standard_normal((n, channels, 64))).astype(np.float32))] for r in rooms}
    info = {r: {"dims": list(dims), "array": {"format": fmt, "centre": list(centre), "yaw": yaw,
                                              "side": side if fmt == "mic4" else None}} for r in rooms}
    return write_bank(path, MemoryBank(fs, fmt, items, info=info))
