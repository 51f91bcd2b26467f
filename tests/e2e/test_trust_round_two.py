"""Trust under attack, round two (issue 42; docs/reliability.md section 10): each class of
hostile situation is handled by the mechanism it belongs to, and tested here through the
real entry point, in this process where it can be. A refused command gives exactly one
``error:`` line and exit 2; nothing outside a command's own paths changes; no scene with
a non-finite sample is ever written; a FIFO is never opened (support.files.Fifo lets any
reader go, so a regression fails instead of hanging)."""
import errno
import json
import os
import shutil
import stat
import subprocess
import sys
import unicodedata
from dataclasses import replace

import h5py
import numpy as np
import pytest

from support.ambience import write_recording
from support.banks import make_native_bank
from support.datasets import make_scene
from support.files import Fifo, data_files
from tsel_data.errors import ConfigError, DatasetError
from tsel_data.store.layout import EXPORT_LOCK_FILE
from tsel_data.store.reader import open_dataset
from tsel_data.store.records import LevelsRecord, NoiseRecord
from tsel_data.store.sanity import scene_problem

DEMO = ["--preset", "demo", "--split", "train=2", "--split", "val=0", "--split", "test=0", "--set",
        "audio.duration=1.0", "--set", "output.shard_size=2"]


@pytest.fixture(scope="module")
def tiny(generated_dataset):
    return generated_dataset("tiny").out


def _copy(src, tmp_path, name="ds") -> str:
    out = str(tmp_path / name)
    shutil.copytree(src, out)
    return out


def _tree(folder) -> dict:
    """Every file below ``folder`` with its bytes' hash: what must not change."""
    return data_files(folder) if os.path.isdir(folder) else {}


# --- 1. one lock for every command that writes into a folder it owns --------------------------------


def _hold(lock_file: str) -> subprocess.Popen:
    """Another process holding ``lock_file`` as an export in progress does."""
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time\n"
                               f"fd = os.open({lock_file!r}, os.O_RDWR | os.O_CREAT)\n"
                               "fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); time.sleep(120)"],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    return holder


@pytest.mark.parametrize("fmt", ["dcase", "webdataset", "hf", "lhotse", "recipes", "card", "captions", "qa"])
def test_a_second_export_into_one_out_is_refused_and_changes_nothing(fmt, tiny, tmp_path, tsel_cli):
    out = tmp_path / "ex"
    tsel_cli.ok("export", "dcase", tiny, "--out", out, "--quiet", "--split", "test")
    before = _tree(out)
    holder = _hold(str(out / EXPORT_LOCK_FILE))
    try:
        line = tsel_cli.refused("export", fmt, tiny, "--out", out, "--quiet", "--force")
        assert "another tsel export is writing into this folder" in line
        assert _tree(out) == before  # the first export's files, journal and manifest as they were
    finally:
        holder.kill()
        holder.wait()
    tsel_cli.ok("export", "dcase", tiny, "--out", out, "--quiet")  # the lock dies with its holder
    manifest = json.load(open(out / ".tsel-export.json"))
    listed = [f for v in manifest["splits"].values() for f in v["files"]] + manifest["files"]
    assert listed and all((out / f).is_file() for f in listed)


def test_a_refused_export_leaves_a_new_or_foreign_folder_as_it_was(tiny, tmp_path, tsel_cli):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    tsel_cli.refused("export", "dcase", tiny, "--out", mine)
    assert sorted(os.listdir(mine)) == ["notes.txt"]
    tsel_cli.refused("export", "dcase", tiny, "--out", tmp_path / "new", "--split", "nope")
    assert not (tmp_path / "new").exists()


# --- 2. one path check for every name read from a file we did not just write ----------------------


NAMES_OUT = ["../victim/x.txt", "{abs}", "sub/../../victim/x.txt", "link/x.txt"]


def _victim(tmp_path):
    (tmp_path / "victim").mkdir(exist_ok=True)
    (tmp_path / "victim" / "x.txt").write_text("mine")
    return str(tmp_path / "victim" / "x.txt")


@pytest.mark.parametrize("where", ["split files", "shared files", "stamps", "journal"])
@pytest.mark.parametrize("name", NAMES_OUT)
def test_an_export_never_deletes_outside_its_folder_whatever_its_manifest_says(where, name, tiny, tmp_path,
                                                                              tsel_cli):
    out = tmp_path / "ex"
    tsel_cli.ok("export", "dcase", tiny, "--out", out, "--quiet", "--split", "test")
    victim = _victim(tmp_path)
    os.symlink(str(tmp_path / "victim"), out / "link")
    name = name.format(abs=victim)
    path = out / ".tsel-export.json"
    doc = json.load(open(path))
    if where == "split files":
        doc["splits"]["test"]["files"].append(name)
    elif where == "shared files":
        doc["files"].append(name)
    elif where == "stamps":
        doc["stamps"][name] = [4, 0]
    else:
        (out / ".tsel-export.journal").write_text(json.dumps(["test", name]) + "\n")
    path.write_text(json.dumps(doc))
    code, _, err = tsel_cli.run("export", "dcase", tiny, "--out", out, "--quiet", "--split", "test")
    assert code in (0, 2) and "Traceback" not in err
    if code == 2 and "link/x.txt" not in name:
        assert "export" in err and name in err.replace("\\\\", "\\")
    tsel_cli.run("export", "dcase", tiny, "--out", out, "--quiet", "--split", "test", "--force")
    assert open(victim).read() == "mine"


def test_release_names_that_leave_the_corpus_or_the_folder_are_refused(release, demo_corpus, tmp_path, tsel_cli):
    rel = _copy(release, tmp_path, "rel")
    _edit_lines(os.path.join(rel, "clips.jsonl"), lambda rows: [{**rows[0], "audio": "../../victim/x.txt"}, *rows[1:]])
    line = tsel_cli.refused("generate", "--from", rel, "--corpus-dir", demo_corpus, "--out", tmp_path / "rb")
    assert "clips.jsonl" in line and "climbs out of its folder" in line
    assert not (tmp_path / "rb").exists() or not os.path.exists(tmp_path / "rb" / "corpus-view")


def test_dataset_json_names_stay_inside_the_dataset(tiny, tmp_path, tsel_cli):
    ds = _copy(tiny, tmp_path)
    victim = _victim(tmp_path)
    doc = json.load(open(os.path.join(ds, "dataset.json")))
    doc["splits"]["test"]["shards"][0]["file"] = "../victim/x.txt"
    json.dump(doc, open(os.path.join(ds, "dataset.json"), "w"))
    assert "climbs out of its folder" in tsel_cli.refused("stats", ds)
    doc["splits"]["test"]["shards"][0]["file"] = "test/shard-00000.h5"
    doc["splits"]["../victim"] = doc["splits"].pop("test")
    json.dump(doc, open(os.path.join(ds, "dataset.json"), "w"))
    assert "is not a plain name" in tsel_cli.refused("export", "webdataset", ds, "--out", tmp_path / "w")
    assert open(victim).read() == "mine" and os.listdir(tmp_path / "victim") == ["x.txt"]


# --- 3. one "is this a regular file we can read" check for every input path ------------------------


def _demo_check(*extra):
    return ["check", *DEMO, *extra]


def _inputs(tiny, tmp_path, demo_corpus, fifo: str) -> dict:
    """Each input path a command reads, given as the FIFO ``fifo``: (argv, needle)."""
    ds = _copy(tiny, tmp_path)
    pred = tmp_path / "pred"
    pred.mkdir()
    return {
        "config": (["check", "--config", fifo, "--no-plan"], "fifo"),
        "hrtf": (_demo_check("--corpus-dir", demo_corpus, "--set", 'scene.format="binaural"', "--set",
                             f'array.hrtf="{fifo}"', "--no-plan"), "fifo"),
        "prediction csv": (["eval", ds, "--dcase", "--pred", pred], "fold3_test-000000.csv"),
        "prediction folder": (["eval", ds, "--dcase", "--pred", fifo], "fifo"),
        "prediction jsonl": (["eval", ds, "--pred", fifo], "fifo"),
        "shard h5": (["stats", ds], "shard-00000.h5"),
        "shard json": (["inspect", ds, "test/0"], "shard-00000.json"),
        "dataset.json": (["verify", ds], "dataset.json"),
        "manifest": (["check", "--preset", "demo", "--manifest", fifo, "--no-plan"], "fifo"),
        "bank": (_demo_check("--corpus-dir", demo_corpus, "--bank", fifo, "--no-plan"), "fifo"),
        "caption embeddings": (_demo_check("--corpus-dir", demo_corpus, "--set", 'scene.similarity="embeddings"',
                                           "--set", f'corpus.caption_embeddings="{fifo}"'), "fifo"),
    }


INPUTS = ["config", "hrtf", "prediction csv", "prediction folder", "prediction jsonl", "shard h5", "shard json",
          "dataset.json", "manifest", "bank", "caption embeddings"]


@pytest.mark.parametrize("what", INPUTS)
def test_a_fifo_given_as_any_input_is_named_never_opened(what, tiny, tmp_path, demo_corpus, tsel_cli):
    fifo = str(tmp_path / "fifo")
    argv, needle = _inputs(tiny, tmp_path, demo_corpus, fifo)[what]
    ds = tmp_path / "ds"
    target = {"prediction csv": tmp_path / "pred" / "fold3_test-000000.csv", "shard h5": ds / "test/shard-00000.h5",
              "shard json": ds / "test/shard-00000.json", "dataset.json": ds / "dataset.json"}.get(what, fifo)
    if os.path.lexists(target):
        os.remove(target)
    with Fifo(target) as f:
        line = tsel_cli.refused(*argv)
    assert not f.opened, f"{what}: the FIFO was opened"
    assert needle in line and "FIFO" in line, line


@pytest.mark.parametrize("kind", ["folder", "loop", "device"])
def test_a_config_or_hrtf_that_is_a_folder_a_loop_or_a_device_is_named_as_such(kind, tmp_path, demo_corpus,
                                                                              tsel_cli):
    p = tmp_path / "x.sofa"
    if kind == "folder":
        p.mkdir()
    elif kind == "loop":
        os.symlink("x.sofa", p)
    else:
        os.symlink(os.devnull, p)
    want = {"folder": "is a folder, not a file", "loop": "is a symbolic link that loops",
            "device": "it is a character device"}[kind]
    assert want in tsel_cli.refused("check", "--config", p, "--no-plan")
    line = tsel_cli.refused(*_demo_check("--corpus-dir", demo_corpus, "--set", 'scene.format="binaural"', "--set",
                                         f'array.hrtf="{p}"', "--no-plan"))
    assert want in line and "not found" not in line


@pytest.mark.parametrize("kind", ["fifo", "file", "loop"])
def test_a_dataset_or_release_folder_that_is_no_folder_is_named_as_such(kind, tmp_path, demo_corpus, tsel_cli):
    p = tmp_path / "d"
    want = {"fifo": "is not a folder: it is a FIFO", "file": "is a file",
            "loop": "is a symbolic link that loops"}[kind]
    if kind == "file":
        p.write_text("x")
    elif kind == "loop":
        os.symlink("d", p)
    with Fifo(p) if kind == "fifo" else _nothing() as f:
        for argv in (["stats", p], ["inspect", p, "test/0"], ["export", "dcase", p, "--out", tmp_path / "ex"],
                     ["check", p], ["generate", "--from", p, "--corpus-dir", demo_corpus, "--out", tmp_path / "rb"]):
            line = tsel_cli.refused(*argv)
            assert want in line and "not found" not in line and "no such" not in line, (argv[0], line)
    assert f is None or not f.opened
    assert not (tmp_path / "ex").exists() and not (tmp_path / "rb").exists()


def test_a_folder_to_read_or_make_where_a_fifo_or_a_file_is_named_as_such(tiny, tmp_path, demo_corpus, tsel_cli):
    (tmp_path / "file").write_text("x")
    with Fifo(tmp_path / "fifo") as f:
        fifo, file = str(tmp_path / "fifo"), str(tmp_path / "file")
        cases = [
            (_demo_check("--corpus-dir", fifo, "--no-plan"), "fifo is not a folder: it is a FIFO"),
            (_demo_check("--corpus-dir", demo_corpus, "--set", f'noise.ambience="{fifo}"', "--no-plan"),
             "fifo is not a folder: it is a FIFO"),
            (["generate", *DEMO, "--corpus-dir", demo_corpus, "--out", fifo], "fifo is not a folder: it is a FIFO"),
            (["generate", *DEMO, "--corpus-dir", demo_corpus, "--out", f"{file}/ds"], "file is a file, not a folder"),
            (["export", "dcase", tiny, "--out", f"{file}/ex"], "file is a file, not a folder"),
            (["inspect", tiny, "test/0", "--png", f"{fifo}/x.png"], "fifo is not a folder: it is a FIFO"),
            (["stats", tiny, "--png", f"{fifo}/sub/x.png"], "fifo is not a folder: it is a FIFO"),
        ]
        for argv, needle in cases:
            line = tsel_cli.refused(*argv)
            assert needle in line and "does not exist" not in line and "not found" not in line, (argv, line)
    assert not f.opened and stat.S_ISFIFO(os.lstat(fifo).st_mode) and open(file).read() == "x"


def test_check_says_a_problem_found_twice_once(demo_corpus, tmp_path, tsel_cli):
    """The embeddings file is looked at for each split: one line, not one per split."""
    code, _, err = tsel_cli.run(*_demo_check("--corpus-dir", demo_corpus, "--set", 'scene.similarity="embeddings"',
                                             "--set", f'corpus.caption_embeddings="{tmp_path}"'))
    assert code == 2 and err.count("is a folder, not a file") == 1, err


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def test_a_dcase_prediction_that_is_dev_zero_is_refused_not_read(tiny, tmp_path, tsel_cli):
    pred = tmp_path / "pred"
    pred.mkdir()
    os.symlink("/dev/zero", pred / "fold3_test-000000.csv")  # read, it grows without end
    assert "it is a character device" in tsel_cli.refused("eval", tiny, "--dcase", "--pred", pred)


def test_a_webdataset_stream_and_a_tau_folder_never_open_a_fifo(tiny, tmp_path, tsel_cli, demo_corpus):
    from support.banks import make_tau_db
    from tsel_data.tools.streaming import SceneStream

    out = tmp_path / "wds"
    tsel_cli.ok("export", "webdataset", tiny, "--out", out, "--quiet", "--split", "test")
    shard = next((out / "test").glob("*.tar"))
    shard.unlink()
    with Fifo(shard) as f, pytest.raises(DatasetError, match="is not a regular file: it is a FIFO"):
        list(SceneStream(str(out), "test"))
    assert not f.opened
    tau = tmp_path / "TAU-SRIR_DB"
    make_tau_db(tau, n_traj=1, heights=(1.2,), n_doa=8, L=64)
    rirs = next(tau.glob("rirs_*.mat"))
    rirs.unlink()
    with Fifo(rirs) as f:
        line = tsel_cli.refused(*_demo_check("--corpus-dir", demo_corpus, "--set", 'scene.format="foa"', "--bank",
                                             tau, "--no-plan"))
    assert not f.opened and "FIFO" in line


# --- 4. --force never replaces what is not a regular file ------------------------------------------


def test_force_never_writes_in_place_of_a_device_a_fifo_or_a_folder(tiny, tmp_path, tsel_cli):
    targets = {"fifo": tmp_path / "fifo.png", "folder": tmp_path / "dir.png"}
    targets["folder"].mkdir()
    if os.geteuid() == 0:  # a real device node: what `--png /dev/null --force` replaced as root
        targets["device"] = tmp_path / "null.png"
        os.mknod(targets["device"], 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    with Fifo(targets["fifo"]) as f:
        for kind, path in targets.items():
            for argv in (["stats", tiny, "--png", path], ["inspect", tiny, "test/0", "--wav", path, "--no-stems"]):
                line = tsel_cli.refused(*argv, "--force")
                assert ("not even with --force" if kind != "folder" else "is a directory") in line, line
    assert not f.opened and stat.S_ISFIFO(os.lstat(targets["fifo"]).st_mode)
    if "device" in targets:
        assert stat.S_ISCHR(os.lstat(targets["device"]).st_mode)


def test_an_export_with_force_never_replaces_a_fifo_in_its_folder(tiny, tmp_path, tsel_cli):
    out = tmp_path / "ex"
    out.mkdir()
    with Fifo(out / "README.md") as f:
        assert "not even with --force" in tsel_cli.refused("export", "card", tiny, "--out", out, "--force")
    assert not f.opened and stat.S_ISFIFO(os.lstat(out / "README.md").st_mode)


# --- 5. one finite-and-sane check on every scene before it is written ------------------------------


def _scene(**levels):
    scene = make_scene("test", 0, rng=np.random.default_rng(0))
    return replace(scene, record=replace(scene.record, levels=replace(scene.record.levels, **levels)))


def test_a_normal_scene_passes_the_last_look_untouched(generated_dataset):
    """No false alarm on what the pipeline makes (the check reads only: bytes unchanged)."""
    for name in ("tiny", "moving"):
        for split in ("train", "test"):
            with open_dataset(generated_dataset(name).out, split) as ds:
                for scene in ds:
                    assert scene_problem(scene) is None, (name, scene.scene_id)


@pytest.mark.parametrize("case,needles", [
    ("nan", ["scene test-000000 holds NaN or Inf samples", "audio.target_level_dbfs = 30 dBFS is above full scale"]),
    ("inf-gain", ["holds NaN or Inf samples", "source 0", "needed a gain of +900 dB", "all but silent"]),
    ("huge", ["samples of amplitude 1e+05"]),
    ("scaled", ["was scaled down by 114 dB", "sensor noise: lower noise.sensor_level"]),
    ("buried", ["target 45 dB below the noise it is labelled over", "diffuse noise: raise noise.diffuse_snr"]),
])
def test_a_scene_unfit_to_be_written_stops_the_shard_naming_the_scene_and_the_setting(case, needles, tmp_path):
    from tsel_data.store.dataset import shard_attrs
    from tsel_data.store.writer import write_shard

    scene = _scene()
    rec = scene.record
    if case == "nan":
        scene = _scene(target_level_dbfs=30.0)
        scene.audio[1, 100] = np.nan
    elif case == "inf-gain":
        scene.audio[0, 0] = np.inf
        scene = replace(scene, record=replace(rec, sources=(replace(rec.sources[0], gain_db=900.0), *rec.sources[1:])))
    elif case == "huge":
        scene.audio[0, 0] = 1e5
    elif case == "scaled":
        scene = replace(scene, record=replace(rec, levels=LevelsRecord(-25.0, 0.99, -114.0),
                                              noise=(NoiseRecord("sensor", None, -13.0),)))
    else:
        scene = replace(scene, record=replace(rec, noise=(NoiseRecord("diffuse", -45.0, 20.0),)))
    with pytest.raises(ConfigError) as e:
        write_shard(str(tmp_path), "test", 0, [scene], shard_attrs(16000, 0.1, "mic4"))
    for n in needles:
        assert n in str(e.value), (n, str(e.value))
    assert not [f for f in os.listdir(tmp_path / "test") if not f.startswith(".")] if (tmp_path / "test").exists() \
        else True


def test_subnormal_rirs_are_refused_by_check_and_never_rendered_into_nan(demo_corpus, tmp_path, tsel_cli):
    bank = make_native_bank(tmp_path / "b.h5")
    with h5py.File(bank, "a") as f:
        rirs = f["rooms/roomA/rirs"][()] * np.float32(1e-42)  # subnormal float32
        del f["rooms/roomA/rirs"]
        f["rooms/roomA/rirs"] = rirs
    argv = [*DEMO, "--corpus-dir", demo_corpus, "--bank", bank, "--set", "splits.train.rooms=[\"roomA\"]", "--set",
            "splits.val.rooms=[\"roomB\"]"]
    assert "is all but silent" in tsel_cli.refused("check", *argv, "--no-plan")
    line = tsel_cli.refused("generate", *argv, "--out", tmp_path / "ds", "--quiet")
    assert "all but silent" in line and "b.h5" in line
    assert not list((tmp_path / "ds").glob("*/shard-*.h5"))


def test_check_catches_the_configs_that_rendered_nan(demo_corpus, tsel_cli):
    line = tsel_cli.refused(*_demo_check("--corpus-dir", demo_corpus, "--set", "audio.target_level_dbfs=1000"))
    assert "audio.target_level_dbfs must be >= -80 and <= 0 dBFS" in line


# --- 6. tsel check with noise.ambience; an all-zero ambience recording -----------------------------


def test_check_plans_with_ambience_as_generate_does_and_refuses_a_silent_recording(demo_corpus, tmp_path, tsel_cli):
    loud, silent = tmp_path / "loud", tmp_path / "silent"
    rng = np.random.default_rng(0)
    write_recording(loud / "hall.wav", 0.01 * rng.standard_normal((4, 3 * 24000)).astype(np.float32), 24000)
    write_recording(silent / "hall.wav", np.zeros((4, 3 * 24000), np.float32), 24000)
    tsel_cli.ok(*_demo_check("--corpus-dir", demo_corpus, "--set", f'noise.ambience="{loud}"'))  # plans every scene
    for cmd in (_demo_check("--corpus-dir", demo_corpus, "--no-plan"),
                ["generate", *DEMO, "--corpus-dir", demo_corpus, "--out", tmp_path / "ds", "--quiet"]):
        line = tsel_cli.refused(*cmd, "--set", f'noise.ambience="{silent}"')
        assert "hall.wav is silent" in line and "no gain gives silence an SNR" in line


# --- 7. one damaged-shard path in the reader that every tool goes through --------------------------


def _damage(ds: str, how: str) -> str:
    h5, js = os.path.join(ds, "test/shard-00000.h5"), os.path.join(ds, "test/shard-00000.json")
    doc = json.load(open(js))
    if how == "labels-list":
        doc = []
    elif how == "scenes-string":
        doc["scenes"] = "x"
    elif how == "no-sources":
        doc["scenes"][0]["sources"] = []
    elif how == "sources-string":
        doc["scenes"][0]["sources"] = "target"
    elif how == "level-string":
        doc["scenes"][0]["levels"] = {"peak": "loud"}
    elif how == "acoustics-string":
        doc["scenes"][0]["sources"][0]["acoustics"] = {"drr_db": "x", "t30_bands_s": {"500": 0.4}}
    elif how == "bands-list":
        doc["scenes"][0]["sources"][0]["acoustics"] = {"drr_db": 1.0, "t30_bands_s": [0.4]}
    elif how in ("no-azimuth", "mics-shape", "ids-short", "active-shape", "no-audio", "nan-audio"):
        with h5py.File(h5, "a") as f:
            if how == "no-azimuth":
                del f["labels/azimuth"]
            elif how == "no-audio":
                del f["audio"]
            elif how == "nan-audio":
                f["audio"][0, 1, 7] = np.nan
            elif how == "mics-shape":
                m = f["mic_positions"][()]
                del f["mic_positions"]
                f["mic_positions"] = m[..., :2]
            elif how == "active-shape":
                a = f["labels/active"][()]
                del f["labels/active"]
                f["labels/active"] = a[:, :, :3]
            else:
                ids = f["scene_id"][()]
                del f["scene_id"]
                f["scene_id"] = ids[:1]
        return "shard-00000.h5"
    json.dump(doc, open(js, "w"))
    return "shard-00000.json"


DAMAGE = ["labels-list", "scenes-string", "no-sources", "sources-string", "level-string", "acoustics-string",
          "bands-list", "no-azimuth", "mics-shape", "ids-short", "active-shape", "no-audio", "nan-audio"]
AUDIO_ONLY = ("no-audio", "nan-audio")  # tools that read labels only (stats) need not open the audio


@pytest.mark.parametrize("how", DAMAGE)
def test_a_shard_of_the_wrong_shape_is_one_line_naming_it_from_every_reader(how, tiny, tmp_path, tsel_cli):
    ds = _copy(tiny, tmp_path)
    shard = _damage(ds, how)
    readers = [["inspect", ds, "test/0"], ["verify", ds, "--split", "test"]]
    readers += [["export", fmt, ds, "--out", tmp_path / fmt, "--split", "test"] for fmt in ("dcase", "webdataset")]
    for argv in readers + ([] if how in AUDIO_ONLY else [["stats", ds, "--split", "test"]]):
        line = tsel_cli.refused(*argv)
        assert shard in line and "damaged shard" in line, (argv[0], line)
    assert not list(tmp_path.glob("dcase/**/*.wav")) and not list(tmp_path.glob("webdataset/**/*.tar"))
    if how in AUDIO_ONLY:
        return
    with pytest.raises(DatasetError, match=shard):
        with open_dataset(ds, "test") as d:
            for scene in d:
                scene.record.sources[0].azimuth


# --- 8. release documents validated on load, seals checked before any work -------------------------


@pytest.fixture(scope="module")
def release(generated_dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("release") / "rel"
    from tsel_data.export import export

    export("recipes", generated_dataset("tiny").out, str(out))
    return str(out)


def _edit_lines(path, fn):
    rows = [json.loads(line) for line in open(path) if line.strip()]
    with open(path, "w") as f:
        f.writelines(r if isinstance(r, str) else json.dumps(r) + "\n" for r in fn(rows))


def _edit_json(path, fn):
    doc = json.load(open(path))
    fn(doc)
    json.dump(doc, open(path, "w"))


def _cut(path):
    lines = open(path).read().splitlines()
    open(path, "w").write(lines[0][: len(lines[0]) // 2] + "\n" + "\n".join(lines[1:]) + "\n")


def _recipe_edit(rows):
    rows[0]["query"] = rows[0]["query"] + " loudly"
    return rows


TAMPER = {
    "version-text": (lambda r: _edit_json(f"{r}/release.json", lambda d: d.update(release_version="1.0")),
                     "release_version is '1.0'"),
    "version-newer": (lambda r: _edit_json(f"{r}/release.json", lambda d: d.update(release_version=9,
                                                                                    version="9.0.0")),
                      "update tsel-data"),
    "checksum-line-gone": (lambda r: _edit_lines(f"{r}/checksums/train.jsonl", lambda rows: rows[1:]),
                           "its scenes are not those of plan/train.jsonl"),
    "clip-without-id": (lambda r: _edit_lines(f"{r}/clips.jsonl", lambda rows: [
        {k: v for k, v in rows[0].items() if k != "clip_id"}, *rows[1:]]), "no key 'clip_id'"),
    "recipe-cut-short": (lambda r: _cut(f"{r}/plan/train.jsonl"), "plan/train.jsonl was edited after the release"),
    "checksum-number": (lambda r: _edit_lines(f"{r}/checksums/train.jsonl", lambda rows: [
        {**rows[0], "audio": 5}, *rows[1:]]), "key 'audio' holds a number, not a string"),
    "checksum-short": (lambda r: _edit_lines(f"{r}/checksums/train.jsonl", lambda rows: [
        {**rows[0], "labels": "abc"}, *rows[1:]]), "not 64 hex digits"),
    "recipe-edited": (lambda r: _edit_lines(f"{r}/plan/train.jsonl", _recipe_edit),
                      "plan/train.jsonl was edited after the release was made"),
    "config-edited": (lambda r: _edit_json(f"{r}/plan/config.json", lambda d: d["config"]["audio"].update(
        target_level_dbfs=-20.0)), "its config was edited after the release was made"),
    "split-name": (lambda r: _edit_json(f"{r}/release.json", lambda d: d["splits"].update(
        {"../x": d["splits"].pop("train")})), "split '../x' is not a plain name"),
    "clips-not-json": (lambda r: open(f"{r}/clips.jsonl", "a").write("[[[\n"), "clips.jsonl:"),
}


@pytest.mark.parametrize("case", sorted(TAMPER))
def test_a_tampered_release_is_one_line_before_any_work(case, release, generated_dataset, demo_corpus, tmp_path,
                                                        tsel_cli):
    rel = _copy(release, tmp_path, "rel")
    tamper, needle = TAMPER[case]
    tamper(rel)
    out = tmp_path / "rb"
    line = tsel_cli.refused("generate", "--from", rel, "--corpus-dir", demo_corpus, "--out", out, "--quiet")
    assert needle in line and "renderer" not in line, line
    assert not list(out.glob("*/shard-*")) if out.exists() else True  # nothing rendered
    code, report, err = tsel_cli.run("check", generated_dataset("tiny").out, "--release", rel)
    assert code == 2 and needle in report + err and "Traceback" not in err  # the release's own problem


# --- 9. stdout and stderr that go away --------------------------------------------------------------


class _Gone:
    """A stdout whose reader went away (or whose disk is full)."""

    def __init__(self, err):
        self.err = err

    def write(self, s):
        raise OSError(self.err, os.strerror(self.err))

    def flush(self):
        pass

    def isatty(self):
        return False


@pytest.mark.parametrize("err,needle", [(errno.EPIPE, "stdout was closed by the program reading it"),
                                        (errno.ENOSPC, "not the dataset's) is full")])
def test_a_stdout_that_goes_away_never_stops_the_work_nor_reads_as_the_dataset(err, needle, capsys, monkeypatch,
                                                                             demo_corpus, tmp_path):
    from tsel_data.cli import main

    monkeypatch.setattr(sys, "stdout", _Gone(err))
    with pytest.raises(SystemExit) as e:
        main(["generate", *DEMO, "--corpus-dir", demo_corpus, "--out", str(tmp_path / "ds"), "--quiet"])
    assert e.value.code == 0
    assert os.path.isfile(tmp_path / "ds" / "dataset.json")
    lines = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("note: ") and needle in lines[0], lines


def test_a_stdout_closed_before_the_command_starts_is_no_traceback(tiny):
    """`tsel stats D >&-`: Python starts with sys.stdout None (a traceback, exit 1, before)."""
    p = subprocess.run(["sh", "-c", 'exec "$0" -m tsel_data.cli stats "$1" >&-', sys.executable, tiny],
                       stderr=subprocess.PIPE, text=True)
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr
    assert p.stderr.startswith("note: stdout could not be written (it was closed before the command started)")


def test_generate_into_a_closed_pipe_finishes_and_says_so(demo_corpus, tmp_path):
    """`tsel generate ... | true` exited 1 without a word, leaving only plan/."""
    p = subprocess.Popen([sys.executable, "-m", "tsel_data.cli", "generate", *DEMO, "--corpus-dir", demo_corpus,
                          "--out", str(tmp_path / "ds")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    p.stdout.close()  # the reader is gone before the first line
    err = p.stderr.read()
    assert p.wait() == 0, err
    assert os.path.isfile(tmp_path / "ds" / "dataset.json") and "Traceback" not in err
    assert "note: stdout was closed" in err


# --- 10. values that crashed are refused by a bound --------------------------------------------------


@pytest.mark.parametrize("argv,needle", [
    (["--set", "scene.speed=1e9", "--set", 'scene.motion="moving"'], "scene.speed must be"),
    (["--set", "scene.tir_db=1e6"], "scene.tir_db must be"),
    (["--set", "scene.tir_db=-1e6"], "scene.tir_db must be"),
    (["--set", "array.capsules=" + "[" * 5000 + "]" * 5000], "nested 5000 levels deep"),
    (["--set", "noise.babble=64"], "noise.babble = 64 asks for 64 babble clips"),
    (["--set", 'noise.sensor="dbfs"', "--set", "noise.sensor_level=100"], "would bury the target"),
    (["--seed", "-1"], "Invalid value for '--seed'"),
    (["--workers", "nan"], "Invalid value for '--workers'"),
])
def test_config_values_that_crashed_are_one_line_in_check(argv, needle, demo_corpus, tsel_cli):
    assert needle in tsel_cli.refused(*_demo_check("--corpus-dir", demo_corpus, *argv))


@pytest.mark.parametrize("argv,needle", [
    (["export", "webdataset", "{ds}", "--out", "{tmp}/w", "--shard-size", "nan"], "size 'nan'"),
    (["export", "hf", "{ds}", "--out", "{tmp}/w", "--shard-size", "inf"], "size 'inf'"),
    (["export", "webdataset", "{ds}", "--out", "{tmp}/w", "--shard-size", "10"], "must be >= 1000"),
    (["verify", "{ds}", "--tolerance", "nan"], "must be a finite number, > 0 and <= 180 deg"),
    (["verify", "{ds}", "--tolerance", "-5"], "must be > 0 and <= 180 deg"),
    (["verify", "{ds}", "--max-scenes", "-1"], "must be >= 1"),
    (["verify", "{ds}", "--fail-under", "2"], "must be >= 0 and <= 1"),
    (["inspect", "{ds}", "--sheet", "{tmp}/s.html", "--scenes", "0"], "must be >= 1"),
])
def test_command_options_out_of_their_bounds_are_one_line(argv, needle, tiny, tmp_path, tsel_cli):
    line = tsel_cli.refused(*[a.format(ds=tiny, tmp=tmp_path) for a in argv])
    assert needle in line, line
    assert not (tmp_path / "w").exists()


def test_a_prediction_too_large_for_a_float_is_one_line(tiny, tmp_path, tsel_cli):
    pred = tmp_path / "p.jsonl"
    pred.write_text('{"scene_id": "test-000000", "azimuth": 1' + "0" * 400 + "}\n")
    assert "a number too large for a float" in tsel_cli.refused("eval", tiny, "--pred", pred)


# --- 11. nonsense accepted silently: DCASE prediction rows ------------------------------------------


@pytest.fixture(scope="module")
def dcase_labels(generated_dataset, tmp_path_factory):
    from tsel_data.export import export

    out = tmp_path_factory.mktemp("dcase") / "ex"
    export("dcase", generated_dataset("tiny").out, str(out), splits=["test"])
    return sorted((out / "metadata_dev" / "dev-test-tsel").glob("*.csv"))


@pytest.mark.parametrize("row,needle", [
    ("3,5,0,10,0,100", "class 5 is not a class of the dataset"),
    ("3,-1,0,10,0,100", "class -1 is not a class"),
    ("3.5,0,0,10,0,100", "frame 3.5 is not a frame number"),
    ("-3,0,0,10,0,100", "frame -3 is not a frame number"),
    ("3,0,-1,10,0,100", "source -1 is not a source index"),
    ("3,0,0,10,0,-100", "distance -100 cm is negative"),
    ("3,0,0,10,400,100", "is not an angle in degrees"),
])
def test_a_dcase_prediction_row_the_dataset_cannot_have_is_refused(row, needle, dcase_labels, tiny, tmp_path,
                                                                   tsel_cli):
    pred = tmp_path / "pred"
    pred.mkdir()
    for p in dcase_labels:
        shutil.copy(p, pred / p.name)
    assert "F" in tsel_cli.ok("eval", tiny, "--dcase", "--pred", pred, "--split", "test")  # the labels score 100 %
    with open(pred / dcase_labels[0].name, "a") as f:
        f.write(row + "\n")
    line = tsel_cli.refused("eval", tiny, "--dcase", "--pred", pred, "--split", "test")
    assert needle in line and f"{dcase_labels[0].name}:" in line, line


# --- 12. Unicode file names match under NFC and NFD --------------------------------------------------


@pytest.mark.parametrize("disk,listed", [("NFD", "NFC"), ("NFC", "NFD")])
def test_a_corpus_copied_from_macos_loses_no_clip(disk, listed, demo_corpus, tmp_path, tsel_cli):
    corpus = tmp_path / "corpus"
    shutil.copytree(demo_corpus, corpus)
    manifest = (corpus / "train.csv").read_text(encoding="utf-8")
    first = manifest.splitlines()[1].split(",")[1]  # a youtube_id: its file is audio/{id}.wav
    on_disk, in_manifest = (unicodedata.normalize(f, "café-oiseau") for f in (disk, listed))
    (corpus / "audio" / f"{first}.wav").rename(corpus / "audio" / f"{on_disk}.wav")
    (corpus / "train.csv").write_text(manifest.replace(first, in_manifest), encoding="utf-8")
    report = json.loads(tsel_cli.ok("check", "--preset", "demo", "--corpus-dir", corpus, "--no-plan", "--json"))
    assert report["facts"]["splits"]["train"]["missing"] == 0, report["warnings"]


def test_a_release_clip_is_found_in_a_copy_that_spells_its_name_the_other_way(tmp_path):
    """A rebuild (`generate --from`) looks a clip up at the release's name first."""
    import hashlib

    from tsel_data.job.relocate import locate_clips

    nfc, nfd = (unicodedata.normalize(f, "café-oiseau") for f in ("NFC", "NFD"))
    (tmp_path / "audio").mkdir()
    (tmp_path / "audio" / f"{nfd}.wav").write_bytes(b"RIFF-bytes")
    entry = {"clip_id": "x", "sha256": hashlib.sha256(b"RIFF-bytes").hexdigest(), "bytes": 10}
    found = locate_clips({f"audio/{nfc}.wav": entry}, str(tmp_path), cfg=None)[f"audio/{nfc}.wav"]
    assert found.same and found.how == "name" and os.path.basename(found.path) == f"{nfd}.wav"
