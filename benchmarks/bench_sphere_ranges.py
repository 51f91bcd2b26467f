"""Rigid spheres with the point-source range dependence, against every image as a plane wave.

    .venv/bin/python benchmarks/bench_sphere_ranges.py [--rooms 12] [--fs 24000]

Each image source near a rigid-sphere receiver (tetra, em32) is heard through the sphere's
response to a point source at its distance, tabulated at a few ranges and interpolated
(acoustics/capsules.py RigidSphere); before, every image was a plane wave. Measures, in
one run and interleaved room by room (the machine may be shared; pairs cancel its drift):

* cost: seconds of ``simulate_rirs`` (hybrid, two sources at 1-3 m, the demo preset's rooms)
  with the range tables (``now``) and with every image a plane wave (``before``: the
  plane-wave range set to 0 m), medians and the median of the paired ratios; the tables'
  one-off build per process is printed apart;
* accuracy: the direct path of a source 1 m and 2.5 m away against the closed form
  (Duda & Martens), the largest error in dB and degrees over the capsules, 300 Hz to 0.8
  Nyquist, both ways.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.acoustics import capsules, simulate_rirs  # noqa: E402
from tsel_data.acoustics.shoebox import shoebox_rirs  # noqa: E402
from tsel_data.acoustics.sphere import rigid_sphere_transfer  # noqa: E402
from tsel_data.core.geometry import Room, array_to_room, sph_to_cart  # noqa: E402
from tsel_data.receivers import ArrayPose  # noqa: E402


def _cost(fmt: str, rooms: int, fs: int) -> None:
    rng = np.random.default_rng(0)
    build = time.perf_counter()
    capsules._sphere_kernels.cache_clear()
    for r in capsules.SPHERE_RANGES:
        capsules._sphere_kernels(fs, 0.042, r)
    build = time.perf_counter() - build
    now, before = [], []
    for _ in range(rooms):
        dims = (rng.uniform(5, 15), rng.uniform(5, 15), rng.uniform(2.5, 4))
        room = Room(dims, float(rng.uniform(0.5, 1.0)))
        centre = (dims[0] / 2, dims[1] / 2, 1.1)
        pose = ArrayPose(fmt, centre, float(rng.uniform(-180, 180)), baffle="rigid")
        pts = array_to_room(sph_to_cart(rng.uniform(-180, 180, 2), rng.uniform(-30, 30, 2), rng.uniform(1, 3, 2)),
                            centre, 0.0)
        for far, out in ((capsules.PLANE_WAVE_RANGE, now), (0.0, before)):
            saved, capsules.PLANE_WAVE_RANGE = capsules.PLANE_WAVE_RANGE, far
            try:
                t = time.perf_counter()
                simulate_rirs(room, pose, pts, fs, method="hybrid", seed=1)
                out.append(time.perf_counter() - t)
            finally:
                capsules.PLANE_WAVE_RANGE = saved
    ratio = np.median(np.array(now) / np.array(before))
    print(f"{fmt:6s} simulate_rirs, 2 sources: now {np.median(now):.3f} s, before {np.median(before):.3f} s, "
          f"ratio {ratio:.2f} (median of {rooms} paired rooms); range tables built once in {build:.2f} s")


def _accuracy(fs: int) -> None:
    free = Room((30.0, 30.0, 30.0), 0.5)
    centre = (15.0, 15.0, 15.0)
    az, el = 30.0, 20.0
    n = 4096
    f = np.fft.rfftfreq(n, 1 / fs)
    band = (f > 300) & (f < 0.8 * fs / 2)
    pose = ArrayPose("tetra", centre, 0.0, baffle="rigid")
    normals = pose.mics() / np.linalg.norm(pose.mics(), axis=1, keepdims=True)
    cos = normals @ sph_to_cart(az, el, 1.0)
    for dist in (1.0, 2.5):
        pt = array_to_room(sph_to_cart(az, el, dist), centre, 0.0)[None]
        w = shoebox_rirs(free, ArrayPose("foa", centre, 0.0), pt, fs, max_order=0).rirs[0, 0]
        want = rigid_sphere_transfer(f, cos, 0.042, distance=dist)[band]
        for name, far in (("now", capsules.PLANE_WAVE_RANGE), ("before", 0.0)):
            saved, capsules.PLANE_WAVE_RANGE = capsules.PLANE_WAVE_RANGE, far
            try:
                h = shoebox_rirs(free, pose, pt, fs, max_order=0).rirs[0]
            finally:
                capsules.PLANE_WAVE_RANGE = saved
            q = (np.fft.rfft(h, n).T / np.fft.rfft(w, n)[:, None])[band] / want
            print(f"tetra, source {dist:g} m, {name:6s}: {np.abs(20 * np.log10(np.abs(q))).max():.2f} dB, "
                  f"{np.degrees(np.abs(np.angle(q))).max():.1f} deg off the point-source series")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rooms", type=int, default=12)
    ap.add_argument("--fs", type=int, default=24000)
    a = ap.parse_args()
    _accuracy(a.fs)
    for fmt in ("tetra", "em32"):
        _cost(fmt, a.rooms, a.fs)


if __name__ == "__main__":
    main()
