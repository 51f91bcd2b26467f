"""Binaural receivers: reading SOFA HRIR files into the head frame, direction weights,
the diffuse-field interaural coherence (tsel_data/acoustics/hrtf.py)."""
import ast
import dataclasses
import pickle
import re

import numpy as np
import pytest

from support.hrtf import BROKEN, grid_directions, make_broken_hrtf, make_hrtf_sofa, spherical_head_hrirs
from tsel_data.acoustics.hrtf import (
    ONSET_MARGIN_S, Hrtf, binaural_coherence, hrtf_diffuse_csd, hrtf_diffuse_weights, hrtf_weights, read_hrtf,
)
from tsel_data.errors import ConfigError
from tsel_data.core.geometry import cart_to_sph, sph_to_cart
from support import REPO


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("hrtf")
    return d


@pytest.fixture(scope="module")
def ref(files):
    return read_hrtf(make_hrtf_sofa(files / "ref.sofa"))


def index_of(hrtf, az, el):
    a, e, _ = cart_to_sph(hrtf.directions)
    hit = np.nonzero((np.abs((a - az + 180) % 360 - 180) < 1e-6) & (np.abs(e - el) < 1e-6))[0]
    assert len(hit) == 1, (az, el)
    return int(hit[0])


def itd(ir_left, ir_right, fs):
    """Right-ear lag (s) behind the left ear: cross-correlation peak, parabolic refinement."""
    x = np.correlate(ir_right.astype(np.float64), ir_left.astype(np.float64), "full")
    k = int(np.argmax(x))
    y0, y1, y2 = x[k - 1], x[k], x[k + 1]
    frac = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    return (k + frac - (len(ir_left) - 1)) / fs


# --- reading ---------------------------------------------------------------------------
def test_fixture_is_read_into_the_head_frame(ref):
    assert ref.fs == 48000 and ref.name == "sphere"
    assert ref.irs.dtype == np.float32 and ref.irs.shape[:2] == (97, 2)
    assert ref.directions.dtype == np.float64
    assert np.allclose(np.linalg.norm(ref.directions, axis=1), 1.0)
    assert np.allclose(ref.directions, grid_directions())
    # 2 ms of leading silence in the file, minus the margin before the earliest ear
    onset = np.argmax(np.abs(ref.irs) >= 0.01 * np.abs(ref.irs).max(axis=-1, keepdims=True), axis=-1)
    assert onset.min() == int(np.ceil(ONSET_MARGIN_S * ref.fs)) and ref.lead > 50

    left = index_of(ref, 90, 0)  # +y: the listener's left
    L, R = ref.irs[left]
    assert np.argmax(np.abs(L)) < np.argmax(np.abs(R))
    assert np.sum(L**2) > 4 * np.sum(R**2)
    assert 0.55e-3 < itd(L, R, ref.fs) < 0.75e-3
    L, R = ref.irs[index_of(ref, -90, 0)]
    assert np.sum(R**2) > 4 * np.sum(L**2)
    assert -0.75e-3 < itd(L, R, ref.fs) < -0.55e-3
    L, R = ref.irs[index_of(ref, 0, 0)]
    assert abs(itd(L, R, ref.fs)) < 1e-5 and np.allclose(L, R)


@pytest.mark.parametrize("kwargs", [
    dict(right_first=True),
    dict(view=(0.0, 1.0, 0.0)),  # the listener looks along +y of the file's frame
    dict(view=(-1.0, 1.0, 0.5), up=(0.0, 0.0, 1.0), listener=(2.0, 1.0, 1.5)),
    dict(view=(0.0, 1.0, 0.0), listener=(2.0, 1.0, 1.5), cartesian=True, right_first=True),
    dict(cartesian=True),
    dict(conventions="GeneralFIR"),
], ids=["right-first", "view-90", "view-tilted-moved", "view-cartesian-right-first", "cartesian", "generalfir"])
def test_file_variants_give_the_same_head_frame(files, ref, kwargs):
    name = "-".join(f"{k}{i}" for i, k in enumerate(kwargs)) + ".sofa"
    h = read_hrtf(make_hrtf_sofa(files / name, **kwargs))
    assert np.allclose(h.directions, ref.directions, atol=1e-9)
    assert h.lead == ref.lead
    assert np.allclose(h.irs, ref.irs, atol=1e-6)


def test_without_receiver_position_the_left_ear_is_first(files, ref):
    h = read_hrtf(make_hrtf_sofa(files / "norec.sofa", receiver_position=False))
    assert np.allclose(h.irs, ref.irs)


def test_data_delay_is_added_to_the_irs(files, ref):
    # integer per-ear delays: exact
    h = read_hrtf(make_hrtf_sofa(files / "delay-int.sofa", delay=[3.0, 7.0]))
    assert h.lead == ref.lead
    assert np.allclose(h.irs[:, :, :ref.n_taps], ref.irs, atol=1e-6)
    # fractional per-measurement delays: windowed-sinc accurate
    d = np.random.default_rng(0).uniform(0.0, 12.0, (97, 2))
    h = read_hrtf(make_hrtf_sofa(files / "delay-frac.sofa", delay=d))
    # the kernel's pre-ringing may start the onset a little earlier; lead keeps file time
    s = ref.lead - h.lead
    assert 0 <= s <= 4
    a, b = h.irs[:, :, s:s + ref.n_taps], ref.irs
    assert np.abs(a - b).max() < 1e-3 * np.abs(b).max()
    i = index_of(ref, 90, 0)
    assert abs(itd(*h.irs[i], h.fs) - itd(*ref.irs[i], ref.fs)) < 2e-6


@pytest.mark.parametrize("fs", [24000, 44100])
def test_resampling_keeps_the_itd(files, ref, fs):
    h = read_hrtf(files / "ref.sofa", fs=fs)
    assert h.fs == fs
    assert abs(h.irs.shape[-1] + h.lead - (ref.irs.shape[-1] + ref.lead) * fs / 48000) <= 2
    i = index_of(h, 90, 0)
    assert 0.55e-3 < itd(*h.irs[i], fs) < 0.75e-3
    assert abs(itd(*h.irs[i], fs) - itd(*ref.irs[i], ref.fs)) < 0.5 / fs
    onset = np.argmax(np.abs(h.irs) >= 0.01 * np.abs(h.irs).max(axis=-1, keepdims=True), axis=-1)
    assert onset.min() <= int(np.ceil(ONSET_MARGIN_S * fs)) + 1


def test_hrtf_is_frozen_and_pickles(ref):
    with pytest.raises(dataclasses.FrozenInstanceError):
        ref.fs = 1.0
    with pytest.raises(ValueError):
        ref.irs[0, 0, 0] = 1.0
    hrtf_weights(ref, ref.directions[:2], "interpolated")
    back = pickle.loads(pickle.dumps(ref))
    assert not back._cache and back.lead == ref.lead and np.array_equal(back.irs, ref.irs)
    assert not back.irs.flags.writeable and repr(back) == repr(ref) and "M=97" in repr(ref)
    assert np.array_equal(hrtf_weights(back, ref.directions[:5], "interpolated")[0],
                          hrtf_weights(ref, ref.directions[:5], "interpolated")[0])


def test_scipy_signal_is_not_imported_at_module_top():
    src = REPO / "tsel_data" / "acoustics" / "hrtf.py"
    top = [n for n in ast.parse(src.read_text()).body if isinstance(n, (ast.Import, ast.ImportFrom))]
    names = [a.name for n in top for a in n.names] + [n.module or "" for n in top if isinstance(n, ast.ImportFrom)]
    assert not any(n.startswith("scipy.signal") for n in names)


# --- weights ---------------------------------------------------------------------------
def test_nearest_weights(ref):
    idx, w = hrtf_weights(ref, ref.directions)
    assert idx.shape == (97, 1) and np.array_equal(idx[:, 0], np.arange(97)) and np.all(w == 1)
    u = np.random.default_rng(1).standard_normal((200, 3))
    idx, w = hrtf_weights(ref, u, mode="nearest")
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    assert np.array_equal(idx[:, 0], np.argmax(u @ ref.directions.T, axis=1))


def test_interpolated_at_a_measured_direction_is_that_one(ref):
    idx, w = hrtf_weights(ref, ref.directions, mode="interpolated")
    assert idx.shape == w.shape == (97, 3)
    k = np.argmax(w, axis=1)
    assert np.array_equal(idx[np.arange(97), k], np.arange(97))
    assert np.allclose(w.max(axis=1), 1.0, atol=1e-9) and np.allclose(w.sum(axis=1), 1.0)


def test_interpolated_between_measurements_uses_the_enclosing_triangle(ref):
    rng = np.random.default_rng(2)
    u = sph_to_cart(rng.uniform(-180, 180, 500), np.degrees(np.arcsin(rng.uniform(np.sin(np.radians(-29)), 1, 500))))
    idx, w = hrtf_weights(ref, u, mode="interpolated")
    assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0)
    assert np.all([len(set(r)) == 3 for r in idx])
    v = np.einsum("nk,nkj->nj", w, ref.directions[idx])
    assert np.allclose(v / np.linalg.norm(v, axis=1, keepdims=True), u, atol=1e-9)  # u lies in the triangle's cone
    assert np.degrees(np.arccos(np.clip(np.einsum("nj,nkj->nk", u, ref.directions[idx]), -1, 1))).max() < 35
    # halfway between two neighbours on the horizontal ring
    idx, w = hrtf_weights(ref, sph_to_cart(7.5, 0.0)[None], mode="interpolated")
    got = {int(i): float(x) for i, x in zip(idx[0], w[0]) if x > 0}
    assert got.keys() == {index_of(ref, 0, 0), index_of(ref, 15, 0)}
    assert np.allclose(list(got.values()), 0.5)


@pytest.mark.parametrize("el", [-45.0, -70.0, -90.0])
def test_interpolated_below_the_lowest_elevation_is_the_nearest(ref, el):
    u = sph_to_cart(np.arange(-180.0, 180.0, 10.0) + 3.0, el)
    idx, w = hrtf_weights(ref, u, mode="interpolated")
    near, _ = hrtf_weights(ref, u)
    assert np.array_equal(idx[:, 0], near[:, 0]) and np.all(w[:, 0] == 1) and np.all(w[:, 1:] == 0)


@pytest.mark.parametrize("elevations", [(0, 30, 60, 90), (10, 40, 70, 90)], ids=["hemisphere", "above-10"])
def test_upper_sets_interpolate_above_and_fall_back_below(files, elevations):
    h = read_hrtf(make_hrtf_sofa(files / f"upper{elevations[0]}.sofa", elevations=elevations, n_taps=64))
    lo = elevations[0]
    az = np.arange(-180.0, 180.0, 7.0)
    above = np.arange(len(az)) % 2 == 0
    u = sph_to_cart(az, np.where(above, lo + 3.0, lo - 3.0))
    idx, w = hrtf_weights(h, u, mode="interpolated")
    assert np.all(w[above].max(axis=1) < 1) and np.all(w[~above, 0] == 1)
    assert np.array_equal(idx[~above, 0], hrtf_weights(h, u[~above])[0][:, 0])
    _, el, _ = cart_to_sph(h.directions)
    want = (np.sin(np.radians(lo + 15)) - np.sin(np.radians(lo))) / (1 - np.sin(np.radians(lo)))
    assert abs(hrtf_diffuse_weights(h)[np.isclose(el, lo)].sum() - want) < 0.01


def test_weights_accept_any_leading_shape_and_refuse_bad_input(ref):
    idx, w = hrtf_weights(ref, np.ones((2, 4, 3)), mode="interpolated")
    assert idx.shape == w.shape == (2, 4, 3)
    with pytest.raises(ValueError, match="unknown HRTF interpolation"):
        hrtf_weights(ref, np.ones((1, 3)), mode="cubic")
    with pytest.raises(ValueError, match="non-zero"):
        hrtf_weights(ref, np.zeros((1, 3)))


def test_a_horizontal_ring_is_interpolated_around_the_ring(files):
    h = read_hrtf(make_hrtf_sofa(files / "ring.sofa", step_az=10.0, elevations=(0,), n_taps=128))
    idx, w = hrtf_weights(h, sph_to_cart(np.array([5.0, -175.0, 20.0]), np.array([0.0, 0.0, 40.0])),
                          mode="interpolated")
    assert np.allclose(w[:2, :2], 0.5) and np.all(w[:, 2] == 0)
    a, _, _ = cart_to_sph(h.directions[idx[:2, :2]])
    assert np.allclose(np.sort(a, axis=1), [[0, 10], [-180, -170]])
    assert np.allclose(hrtf_diffuse_weights(h), 1 / 36)


# --- diffuse field ---------------------------------------------------------------------
def test_diffuse_weights_are_voronoi_areas_of_the_measured_region(files, ref):
    w = hrtf_diffuse_weights(ref)
    assert w.shape == (97,) and np.all(w > 0) and np.isclose(w.sum(), 1.0)
    _, el, _ = cart_to_sph(ref.directions)
    # the measured region ends at the -30° ring: its cells reach down to it only
    band = lambda lo, hi: (np.sin(np.radians(hi)) - np.sin(np.radians(lo))) / 1.5
    for e, lo, hi in [(-30, -30, -15), (0, -15, 15), (60, 45, 75), (90, 75, 90)]:
        assert abs(w[np.isclose(el, e)].sum() - band(lo, hi)) < 0.01 * band(lo, hi) + 0.002
    full = read_hrtf(make_hrtf_sofa(files / "full.sofa", elevations=(-90, -60, -30, 0, 30, 60, 90), n_taps=64))
    w, u = hrtf_diffuse_weights(full), full.directions
    assert np.allclose(w @ u, 0.0, atol=1e-9)
    assert np.allclose(np.einsum("m,mi,mj->ij", w, u, u), np.eye(3) / 3, atol=0.01)


def test_diffuse_coherence_of_the_spherical_head(ref):
    f = np.array([50.0, 100.0, 150.0, 200.0, 1500.0, 2000.0, 3000.0, 4000.0, 6000.0, 8000.0])
    csd = hrtf_diffuse_csd(ref, f)
    assert csd.shape == (10, 2, 2) and csd.dtype == np.complex128
    assert np.allclose(csd, np.conj(np.swapaxes(csd, 1, 2)))
    assert np.all(csd[:, 0, 0].real > 0) and np.allclose(csd[:, 0, 0].imag, 0, atol=1e-12)
    assert abs(csd[0, 0, 0].real + csd[0, 1, 1].real - 2.0) < 0.1  # unit-DC HRIRs: mean ear power ~1
    coh = binaural_coherence(csd)
    assert np.all(coh[:2] > 0.97) and np.all(coh[2:4] > 0.85)
    assert np.all(coh[4:] < 0.5)
    # the same Φ as a direct DTFT sum
    k = np.arange(ref.n_taps)
    H = ref.irs.astype(np.float64) @ np.exp(-2j * np.pi * np.outer(k, f[[1, 5]]) / ref.fs)
    direct = np.einsum("m,maf,mbf->fab", hrtf_diffuse_weights(ref), H, np.conj(H))
    assert np.allclose(csd[[1, 5]], direct, rtol=1e-9, atol=1e-12)


# --- malformed files -------------------------------------------------------------------
@pytest.mark.parametrize("kind", BROKEN)
def test_malformed_files_are_one_line_config_errors(tmp_path, kind):
    path = make_broken_hrtf(tmp_path / f"broken-{kind}.sofa", kind)
    with pytest.raises(ConfigError, match=re.escape(path.name)) as e:
        read_hrtf(path)
    assert "\n" not in str(e.value)
    want = {"text": "not a SOFA file", "hdf5": "not a SOFA file", "conventions": "not an HRTF",
            "tf": "transfer functions", "receivers": "3 receivers", "no_rate": "SamplingRate",
            "nan_positions": "NaN", "no_positions": "SourcePosition", "few_directions": "distinct source directions",
            "negative_delay": "negative Data.Delay"}[kind]
    assert want in str(e.value)


def test_missing_file_and_bad_rate(tmp_path, files):
    with pytest.raises(ConfigError, match="nowhere.sofa.*not found"):
        read_hrtf(tmp_path / "nowhere.sofa")
    with pytest.raises(ConfigError, match="ref.sofa"):
        read_hrtf(files / "ref.sofa", fs=-1)


def test_hrtf_can_be_built_in_memory():
    u = grid_directions(30.0, (-60, 0, 60))
    h = Hrtf(fs=16000, directions=2 * u, irs=spherical_head_hrirs(u, 16000, 32), lead=0, source="", name="model")
    assert np.allclose(np.linalg.norm(h.directions, axis=1), 1) and h.irs.dtype == np.float32
    with pytest.raises(ValueError, match="irs has shape"):
        Hrtf(fs=16000, directions=u, irs=np.zeros((3, 2, 8)), lead=0, source="", name="bad")


def test_a_sofa_file_written_by_sofar_reads_the_same(tmp_path, ref):
    """The reader against the SOFA reference implementation's writer (sofar, the test
    extra): the same HRIRs and directions as the netCDF4-written fixture."""
    sofar = pytest.importorskip("sofar")
    sofa = sofar.Sofa("SimpleFreeFieldHRIR")
    sofa.Data_SamplingRate = 48000.0
    az, el, _ = cart_to_sph(grid_directions())
    sofa.SourcePosition = np.stack([az, el, np.full(len(az), 1.2)], axis=1)
    sofa.SourcePosition_Type, sofa.SourcePosition_Units = "spherical", "degree, degree, metre"
    sofa.Data_IR = spherical_head_hrirs(grid_directions(), fs=48000)
    sofa.GLOBAL_ListenerShortName = "sphere"
    path = tmp_path / "sofar.sofa"
    sofar.write_sofa(str(path), sofa, compression=0)
    got = read_hrtf(path)
    assert got.fs == ref.fs and got.name == "sphere" and got.lead == ref.lead
    assert np.allclose(got.directions, ref.directions, atol=1e-12)
    assert np.array_equal(got.irs, ref.irs)


def test_onsets_are_the_heads_delays_and_aligned_irs_line_up(ref):
    """Each IR's onset (its lag behind its minimum-phase version) follows the spherical
    head's Woodworth delay at its ear within a sample, over every direction; the aligned IRs
    (onsets removed) all peak within a sample of one another."""
    from support.hrtf import woodworth_delays
    from tsel_data.acoustics.hrtf import aligned_hrirs, hrir_onsets

    on = hrir_onsets(ref)
    assert on.shape == (len(ref.directions), 2)
    excess = on - woodworth_delays(ref.directions) * ref.fs  # the common part: the file's onset, less the lead
    assert np.ptp(excess) < 1.0, np.ptp(excess)
    aligned, lead = aligned_hrirs(ref)
    assert aligned.shape == ref.irs.shape and lead > 0
    peaks = np.argmax(np.abs(aligned), axis=-1)
    assert np.ptp(peaks) <= 1, np.unique(peaks)
    assert np.ptp(np.argmax(np.abs(ref.irs), axis=-1)) > 20  # as measured they do not (the ITD alone is ~30)
