"""Recorded ambience (tsel_data/corpus/ambience.py): the layouts are found from headers, bank rooms
find their own room's recording, segments are exactly the file's samples at the drawn
offset, the SNR is exactly the DCASE generator's, and every bad input is one line."""
import math
import os

import numpy as np
import pytest
import soundfile as sf

from support.ambience import (DCASE_FOLDERS, TAU_SNOISE_FOLDERS, make_tau_snoise, make_user_folder,
                              write_recording, signature)
from tsel_data.corpus import ambience
from tsel_data.corpus.ambience import find_ambience, omni_energy, snr_gain
from tsel_data.errors import ConfigError

FS = 24000
N = 2400  # 0.1 s scenes: 5 blocks of a 0.5 s recording


@pytest.fixture(scope="module")
def tau(tmp_path_factory):
    root = tmp_path_factory.mktemp("TAU-SNoise_DB")
    return root, make_tau_snoise(root)


@pytest.fixture(scope="module")
def dcase(tmp_path_factory):
    root = tmp_path_factory.mktemp("dcase-noise")
    return root, make_tau_snoise(root, rooms=DCASE_FOLDERS)


def which(truth, seg, tag):
    """(folder, offset) of the recording in ``truth`` that holds ``seg`` [C, n], or None."""
    n = seg.shape[1]
    for folder, files in truth.items():
        x = files[tag] if tag else files
        for off in range(x.shape[1] - n + 1):
            if x[0, off] == seg[0, 0] and np.array_equal(x[:, off:off + n], seg):
                return folder, off
    return None


def one_line(excinfo, *names):
    msg = str(excinfo.value)
    assert "\n" not in msg, msg
    for name in names:
        assert str(name) in msg, msg
    return msg


# --- discovery ---------------------------------------------------------------------------------

@pytest.mark.parametrize("fmt,tag", [("foa", "foa_sn3d"), ("tetra", "tetra"), ("mic", "tetra")])
def test_tau_layout_picks_the_receivers_file_in_every_room(tau, fmt, tag):
    root, _ = tau
    amb = find_ambience(root, channels=4, fs=FS, fmt=fmt)
    assert amb.rooms == TAU_SNOISE_FOLDERS and not amb.flat
    for folder, rec in amb.by_room.items():
        assert rec.path == str(root / folder / f"ambience_{tag}_24k_edited.wav")
        assert (rec.room, rec.channels, rec.fs, rec.frames) == (folder, 4, FS, FS // 2)


def test_discovery_reads_headers_only(tau, monkeypatch):
    def no_read(*a, **k):
        raise AssertionError("discovery read audio")

    monkeypatch.setattr(sf, "read", no_read)
    monkeypatch.setattr(sf.SoundFile, "read", no_read)
    find_ambience(tau[0], channels=4, fs=FS, fmt="foa")


def test_tag_table_covers_the_tau_receivers():
    assert set(ambience.AMBIENCE_FILE_TAGS.values()) == {"foa", "tetra"}
    assert ambience._TAU_FILE.match("ambience_foa_sn3d_24k_edited.wav").group("tag") == "foa_sn3d"


# --- room matching -----------------------------------------------------------------------------

BANK_ROOMS = {  # TAU-SRIR DB room (rirs_NN_<room>.mat) -> its TAU-SNoise_DB folder
    "bomb_shelter": "01_bomb_center", "gym": "02_gym", "pb132": "03_pb132_paatalo_classroom2",
    "pc226": "04_pc226_paatalo_office", "sa203": "05_sa203_sahkotalo_lecturehall",
    "sc203": "06_sc203_sahkotalo_classroom2", "se203": "08_se203_sahkotalo_classroom",
    "tb103": "09_tb103_tietotalo_lecturehall", "tc352": "10_tc352_tietotalo_meetingroom",
}
NUMBERS = {"bomb_shelter": 1, "gym": 2, "pb132": 3, "pc226": 4, "sa203": 5, "sc203": 6, "se203": 8,
           "tb103": 9, "tc352": 10}


@pytest.mark.parametrize("room", sorted(BANK_ROOMS))
def test_bank_rooms_match_their_folder_by_name_and_number(tau, dcase, room):
    amb = find_ambience(tau[0], 4, FS, "foa")
    assert amb.for_room(room).room == BANK_ROOMS[room]
    assert amb.for_room(NUMBERS[room]).room == BANK_ROOMS[room]
    assert amb.for_room(str(NUMBERS[room])).room == BANK_ROOMS[room]
    assert amb.for_room(BANK_ROOMS[room]).room == BANK_ROOMS[room]
    unprefixed = dict(zip(TAU_SNOISE_FOLDERS, DCASE_FOLDERS))[BANK_ROOMS[room]]
    d = find_ambience(dcase[0], 4, FS, "tetra")
    assert d.for_room(room).room == unprefixed
    assert d.for_room(NUMBERS[room]).room == unprefixed


def test_se203_is_not_se201(tmp_path):
    make_tau_snoise(tmp_path, rooms=("se201_sahkotalo_classroom", "se203_sahkotalo_classroom"))
    amb = find_ambience(tmp_path, 4, FS, "foa")
    assert amb.for_room("se203").room == "se203_sahkotalo_classroom"
    assert amb.for_room(7).room == "se201_sahkotalo_classroom"


def test_simulated_rooms_draw_any_recording_from_the_scene_generator(tau):
    amb = find_ambience(tau[0], 4, FS, "foa")
    a = [amb.for_room(None, np.random.default_rng(s)).room for s in range(40)]
    b = [amb.for_room(None, np.random.default_rng(s)).room for s in range(40)]
    assert a == b and len(set(a)) > 4
    with pytest.raises(ValueError):
        amb.for_room(None)


def test_user_room_folders_and_flat_folder(tmp_path):
    rooms = make_user_folder(tmp_path / "rooms", ["kitchen", "gym"], channels=2)
    amb = find_ambience(tmp_path / "rooms", channels=2, fs=FS, fmt="mic4")  # fmt is not needed here
    assert amb.for_room("kitchen").path.endswith("kitchen.flac") and amb.for_room(2).room == "gym"
    _, seg = amb.for_room("gym").segment(np.random.default_rng(0), N)
    assert which(rooms, seg, None)[0] == "gym"

    flat = make_user_folder(tmp_path / "flat", ["a", "b", "c"], suffix=".wav", per_room=False)
    f = find_ambience(tmp_path / "flat", channels=4, fs=FS)
    assert f.flat and len(f.recordings) == 3
    picks = {f.for_room("pb132", np.random.default_rng(s)).path for s in range(30)}
    assert picks == {str(tmp_path / "flat" / f"{n}.wav") for n in flat}
    one = make_user_folder(tmp_path / "one", ["only"], per_room=False)
    assert find_ambience(tmp_path / "one", 4, FS).for_room("gym").path.endswith("only.flac")  # no rng needed


# --- segments ----------------------------------------------------------------------------------

def test_random_segment_is_the_rooms_samples_at_the_drawn_offset(tau):
    root, truth = tau
    amb = find_ambience(root, 4, FS, "tetra")
    for room, folder in BANK_ROOMS.items():
        rng = np.random.default_rng(NUMBERS[room])
        offset, seg = amb.for_room(room).segment(rng, N)
        expect = np.random.default_rng(NUMBERS[room]).integers(0, FS // 2 - N + 1)
        assert offset == expect
        assert seg.dtype == np.float32 and seg.shape == (4, N)
        np.testing.assert_array_equal(seg, truth[folder]["tetra"][:, offset:offset + N])
        assert which(truth, seg, "tetra") == (folder, offset)  # no other room holds these samples


def test_same_seed_same_segment_and_seeds_differ(tau):
    rec = find_ambience(tau[0], 4, FS, "foa").for_room("gym")
    a = rec.segment(np.random.default_rng(7), N)
    b = rec.segment(np.random.default_rng(7), N)
    assert a[0] == b[0] and np.array_equal(a[1], b[1])
    assert len({rec.segment(np.random.default_rng(s), N)[0] for s in range(10)}) > 5
    # exactly one draw from the scene's generator: the next draw is the one after it
    used, fresh = np.random.default_rng(3), np.random.default_rng(3)
    rec.segment(used, N)
    fresh.integers(0, FS // 2 - N + 1)
    assert used.integers(1 << 30) == fresh.integers(1 << 30)


def test_consecutive_rule_gives_consecutive_blocks_and_wraps(tau):
    root, truth = tau
    rec = find_ambience(root, 4, FS, "foa").for_room("pc226")
    x = truth["04_pc226_paatalo_office"]["foa_sn3d"]
    assert rec.blocks(N) == 5
    for i in range(12):
        offset, seg = rec.segment(None, N, rule="consecutive", index=i)
        assert offset == (i % 5) * N
        np.testing.assert_array_equal(seg, x[:, offset:offset + N])
    blocks = np.concatenate([rec.segment(None, N, "consecutive", i)[1] for i in range(5)], axis=1)
    np.testing.assert_array_equal(blocks, x[:, :5 * N])


def test_segment_reads_only_its_samples(tau, monkeypatch):
    rec = find_ambience(tau[0], 4, FS, "foa").for_room(1)
    calls = []
    real = sf.read

    def spy(*a, **k):
        calls.append(k)
        return real(*a, **k)

    monkeypatch.setattr(sf, "read", spy)
    offset, _ = rec.segment(np.random.default_rng(0), N)
    assert calls == [dict(start=offset, stop=offset + N, dtype="float32", always_2d=True)]


def test_a_scene_as_long_as_the_recording_fits_exactly(tau):
    rec = find_ambience(tau[0], 4, FS, "foa").for_room("gym")
    offset, seg = rec.segment(np.random.default_rng(0), rec.frames)
    assert offset == 0 and seg.shape == (4, rec.frames)


# --- level -------------------------------------------------------------------------------------

def snr_by_definition(target, noise, channels):
    """The DCASE generator's SNR, written out independently: energy of the channel mean."""
    t = target[channels].astype(np.float64).mean(axis=0)
    n = noise[channels].astype(np.float64).mean(axis=0)
    return 10 * math.log10(np.sum(t ** 2) / np.sum(n ** 2))


@pytest.mark.parametrize("level_channels,as_listed", [((0,), [0]), ((), [0, 1, 2, 3]), (slice(0, 1), [0]),
                                                       ((1, 3), [1, 3])])
@pytest.mark.parametrize("snr", [6.0, 17.5, 30.0, -3.0])
def test_snr_gain_gives_exactly_the_snr(level_channels, as_listed, snr):
    rng = np.random.default_rng(1)
    target = np.zeros((4, 12000), dtype=np.float32)
    target[:, 3000:7000] = rng.standard_normal((4, 4000)) * np.array([[1.0], [0.3], [0.2], [0.5]])
    noise = (0.05 * rng.standard_normal((4, 12000)) + 0.01).astype(np.float32)
    g = snr_gain(target, noise, snr, level_channels)
    assert abs(snr_by_definition(target, g * noise.astype(np.float64), as_listed) - snr) < 1e-9


def test_foa_level_is_w_alone_and_mic_level_is_the_mean():
    rng = np.random.default_rng(2)
    x = rng.standard_normal((4, 1000))
    assert omni_energy(x, (0,)) == pytest.approx(np.sum(x[0] ** 2), rel=1e-12)
    assert omni_energy(x, ()) == pytest.approx(np.sum(x.mean(axis=0) ** 2), rel=1e-12)
    assert omni_energy(x, None) == omni_energy(x, ())
    # the mean, not the sum of energies: channels in antiphase cancel
    assert omni_energy(np.stack([x[0], -x[0]]), ()) == 0.0
    # a gain independent of silence: padding both with zeros changes nothing
    t, n = rng.standard_normal((4, 500)), rng.standard_normal((4, 500))
    pad = lambda a: np.pad(a, ((0, 0), (0, 700)))
    assert snr_gain(pad(t), pad(n), 10.0, (0,)) == pytest.approx(snr_gain(t, n, 10.0, (0,)), rel=1e-12)


def test_snr_gain_edges():
    assert snr_gain(np.zeros((4, 10)), np.ones((4, 10)), 10.0, ()) == 0.0
    with pytest.raises(ValueError, match="silent"):
        snr_gain(np.ones((4, 10)), np.zeros((4, 10)), 10.0, ())
    with pytest.raises(ValueError, match="whole scene"):
        snr_gain(np.ones((4, 10)), np.ones((4, 9)), 10.0, ())


# --- errors: one ConfigError line naming the folder or file --------------------------------------

def test_missing_root_and_not_a_folder(tmp_path):
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "nope", 4, FS, "foa")
    one_line(e, tmp_path / "nope", "not found")
    (tmp_path / "file.wav").write_bytes(b"")
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "file.wav", 4, FS, "foa")
    one_line(e, "file.wav", "not a folder")


def test_bank_room_without_a_folder_names_it_and_lists_the_folders(tmp_path):
    make_tau_snoise(tmp_path, rooms=TAU_SNOISE_FOLDERS[:2])
    amb = find_ambience(tmp_path, 4, FS, "foa")
    with pytest.raises(ConfigError) as e:
        amb.for_room("tc352")
    one_line(e, tmp_path, "'tc352'", "TAU room 10", "01_bomb_center, 02_gym")
    with pytest.raises(ConfigError) as e:
        amb.for_room(7)
    one_line(e, "bank room 7 (TAU room 07)", "01_bomb_center")


def test_wrong_channel_count_and_rate(tmp_path):
    make_tau_snoise(tmp_path / "a", rooms=("02_gym",), channels=2)
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "a", 4, FS, "foa")
    one_line(e, tmp_path / "a" / "02_gym" / "ambience_foa_sn3d_24k_edited.wav", "2 channels", "has 4")
    make_tau_snoise(tmp_path / "b", rooms=("02_gym",))
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "b", 4, 48000, "foa")
    one_line(e, "ambience_foa_sn3d_24k_edited.wav", "24000 Hz", "resample it to 48000 Hz")


def test_unreadable_and_empty_files(tmp_path):
    (tmp_path / "r" / "gym").mkdir(parents=True)
    (tmp_path / "r" / "gym" / "gym.wav").write_bytes(b"RIFF....not a wav at all" * 10)
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "r", 4, FS)
    one_line(e, tmp_path / "r" / "gym" / "gym.wav", "cannot read")
    (tmp_path / "e").mkdir()
    (tmp_path / "e" / "x.flac").write_bytes(b"")
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "e", 4, FS)
    one_line(e, tmp_path / "e" / "x.flac", "empty")


def test_short_recordings_are_refused_not_tiled(tau):
    with pytest.raises(ConfigError) as e:
        find_ambience(tau[0], 4, FS, "foa", scene_samples=FS)
    one_line(e, "01_bomb_center/ambience_foa_sn3d_24k_edited.wav", "shorter than one scene", "not tiled")
    rec = find_ambience(tau[0], 4, FS, "foa").for_room("gym")
    with pytest.raises(ConfigError) as e:
        rec.segment(np.random.default_rng(0), FS)
    one_line(e, rec.path, "0.500 s long")


def test_receiver_without_a_tau_file_and_missing_tag(tmp_path):
    make_tau_snoise(tmp_path / "t", rooms=("02_gym",))
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "t", 4, FS, "mic4")
    one_line(e, tmp_path / "t" / "02_gym", "'mic4'", "foa_sn3d (foa)")
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "t", 4, FS)
    one_line(e, "02_gym", "several receivers")
    make_tau_snoise(tmp_path / "f", rooms=("02_gym",), tags=("foa_sn3d",))
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "f", 4, FS, "tetra")
    one_line(e, tmp_path / "f" / "02_gym", "ambience_tetra_24k_edited.wav")
    assert find_ambience(tmp_path / "f", 4, FS).for_room("gym").path.endswith("foa_sn3d_24k_edited.wav")


def test_layout_problems(tmp_path):
    make_user_folder(tmp_path / "mixed", ["gym"])
    make_user_folder(tmp_path / "mixed", ["loose"], per_room=False)
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "mixed", 4, FS)
    one_line(e, tmp_path / "mixed", "both")
    make_user_folder(tmp_path / "two", ["gym"])
    write_recording(tmp_path / "two" / "gym" / "other.wav", signature("o", "o", 100, 4), FS)
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "two", 4, FS)
    one_line(e, tmp_path / "two" / "gym", "2 recordings", "flat folder")
    (tmp_path / "empty" / "notes").mkdir(parents=True)
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "empty", 4, FS)
    one_line(e, tmp_path / "empty", "no recordings")
    make_user_folder(tmp_path / "rooms", ["gym"])
    (tmp_path / "rooms" / "pb132").mkdir()
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path / "rooms", 4, FS)
    one_line(e, tmp_path / "rooms" / "pb132", "holds no recordings")


def test_a_room_matching_two_folders_is_refused(tmp_path):
    make_tau_snoise(tmp_path, rooms=("02_gym", "gym"))
    amb = find_ambience(tmp_path, 4, FS, "foa")
    assert amb.for_room("gym").room == "gym"  # the exact name wins
    with pytest.raises(ConfigError) as e:
        amb.for_room(2)
    one_line(e, tmp_path, "02_gym, gym", "keep one")


def test_parent_of_the_tau_folder_is_pointed_down(tmp_path):
    make_tau_snoise(tmp_path / "TAU-SNoise_DB", rooms=("02_gym",))
    with pytest.raises(ConfigError) as e:
        find_ambience(tmp_path, 4, FS, "foa")
    one_line(e, tmp_path / "TAU-SNoise_DB", "point there")


def test_truncated_file_and_bad_rule(tmp_path):
    make_tau_snoise(tmp_path, rooms=("02_gym",), tags=("foa_sn3d",))
    amb = find_ambience(tmp_path, 4, FS, "foa")
    rec = amb.for_room("gym")
    path = rec.path
    size = os.path.getsize(path)
    with open(path, "r+b") as f:  # cut the data, keep the header's declared length
        f.truncate(size // 2)
    with pytest.raises(ConfigError) as e:
        rec.segment(None, N, "consecutive", 4)
    one_line(e, path)
    with pytest.raises(ConfigError) as e:
        rec.segment(None, N, "sometimes")
    one_line(e, "sometimes", "random, consecutive")


def test_nan_samples_are_refused(tmp_path):
    x = signature("nan", "user", 5000, 4)
    x[2, 100] = np.nan
    write_recording(tmp_path / "flat" / "n.wav", x, FS)
    rec = find_ambience(tmp_path / "flat", 4, FS).recordings[0]
    with pytest.raises(ConfigError) as e:
        rec.segment(None, 1000, "consecutive", 0)
    one_line(e, rec.path, "NaN")
    assert rec.segment(None, 1000, "consecutive", 1)[1].shape == (4, 1000)
