"""One line for every failure, messages that point the right way, paths that stay private
(issue 24 §3-5, issue 26 §3; docs/reliability.md section 9). One test per class; each
refused command gives exactly one ``error:`` line and exit 2 (``tsel_cli.refused``)."""
import errno
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest
import soundfile as sf

from support.banks import make_tau_db
from support.datasets import make_dataset
from tsel_data.core import atomic
from tsel_data.store import writer


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("messages") / "ds"
    make_dataset(root, splits={"train": 2, "test": 2})
    return str(root)


DEMO_RUN = ["--preset", "demo", "--split", "train=2", "--split", "val=0", "--split", "test=0", "--set",
            "audio.duration=1.0", "--set", "output.shard_size=1"]


def _corpus(root, monkeypatch, rows=3, caption="a dog barks"):
    """A three-clip AudioCaps-format corpus: manifest train.csv, audio/clipN.wav."""
    (root / "audio").mkdir(parents=True)
    rng = np.random.default_rng(0)
    lines = ["audiocap_id,youtube_id,start_time,caption"]
    for i in range(rows):
        sf.write(root / "audio" / f"clip{i}.wav", 0.1 * rng.standard_normal(16000).astype(np.float32), 16000)
        lines.append(f"{i},clip{i},0,{caption} {i}")
    (root / "train.csv").write_text("\n".join(lines) + "\n")
    monkeypatch.chdir(root.parent)  # messages name files relative to the working folder
    return root


def _config(tmp_path, corpus):
    """A config over a corpus with a train split only, bad clips failing the run; the
    working folder is ``tmp_path`` (messages name files relative to it)."""
    path = tmp_path / "c.toml"
    path.write_text(textwrap.dedent(f"""
        on_bad_clip = "fail"
        [corpus]
        dir = "{corpus}"
        [splits.train]
        manifest = "train.csv"
        count = 2
    """))
    return ["--config", str(path), "--no-plan"]


# --- §3: one line, never a traceback ------------------------------------------------------------


def test_a_dask_cluster_that_cannot_start_is_one_line(demo_corpus, tsel_cli, tmp_path, monkeypatch):
    distributed = pytest.importorskip("dask.distributed")

    def nanny_dies(*a, **k):  # what dask raises when a worker is killed while the cluster starts
        try:
            raise RuntimeError("Nanny failed to start worker process")
        except RuntimeError as e:
            raise RuntimeError("Nanny failed to start.") from e

    monkeypatch.setattr(distributed, "LocalCluster", nanny_dies)
    line = tsel_cli.refused("generate", *DEMO_RUN, "--corpus-dir", demo_corpus, "--out", tmp_path / "out",
                            "--executor", "dask-local", "--workers", "2", "--quiet")
    assert "the local Dask cluster did not start (Nanny failed to start worker process)" in line
    assert "--executor local" in line and "--resume" not in line


def test_a_stop_signal_while_pool_workers_start_is_no_traceback(tmp_path):
    # the signal lands inside fork itself (an at-fork hook sends it): before, the stop was
    # raised in the parent's at-fork hooks, printed as "Exception ignored" with a traceback
    script = textwrap.dedent("""
        import os, signal
        from tsel_data.runtime import runner as ex
        sent = []
        def in_fork():
            if not sent:
                sent.append(1)
                os.kill(os.getpid(), signal.SIGTERM)
        os.register_at_fork(after_in_parent=in_fork)
        with ex.stop_signals():
            try:
                with ex.Runner("local", 2):
                    print("not stopped")
            except ex.Stopped as e:
                print("stopped", e.code)
    """)
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path)
    assert r.stdout.split() == ["stopped", "143"], r.stdout + r.stderr
    assert "Traceback" not in r.stderr and "Exception ignored" not in r.stderr, r.stderr


def test_a_stop_while_the_dask_cluster_starts_leaves_no_leaked_semaphores(tmp_path):
    # Ctrl-C while the cluster starts: a thread that does not block it (tqdm's monitor)
    # takes it, and Python runs the handler in the main thread, inside LocalCluster(...).
    # Before, the stop left the cluster half made and unnamed, never closed: multiprocessing's
    # resource tracker then said "There appear to be 12 leaked semaphore objects" on the way out
    pytest.importorskip("dask.distributed")
    script = textwrap.dedent("""
        import os, signal
        import dask.distributed
        from tsel_data.runtime import runner as ex

        class Interrupted(dask.distributed.LocalCluster):
            def __init__(self, *a, **k):
                super().__init__(*a, **k)
                old = signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
                signal.raise_signal(signal.SIGINT)  # its handler runs here, now
                signal.pthread_sigmask(signal.SIG_SETMASK, old)

        if __name__ == "__main__":
            dask.distributed.LocalCluster = Interrupted
            with ex.stop_signals():
                try:
                    with ex.Runner("dask-local", 2):
                        print("not stopped")
                except ex.Stopped as e:
                    print("stopped", e.code, flush=True)
                    os._exit(e.code)  # as `tsel` leaves after a stop
    """)
    # (the resource tracker holds stderr open until it has said its last)
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert r.stdout.split() == ["stopped", "130"], r.stdout + r.stderr
    assert "leaked" not in r.stderr and "Traceback" not in r.stderr, r.stderr


# --- §4 and §5: a full disk is one line that says how to go on for this command ---------------------


def _no_space(*a, **k):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_full_disk_advises_resume_only_where_the_command_has_it(demo_corpus, dataset, tsel_cli, tmp_path,
                                                                  monkeypatch):
    monkeypatch.setattr(atomic, "_fsync_file", _no_space)  # every whole-file write of atomic_output
    for argv in (["inspect", dataset, "test/0", "--png", tmp_path / "x.png"],
                 ["stats", dataset, "--png", tmp_path / "s.png"],
                 ["export", "dcase", dataset, "--out", tmp_path / "exp", "--quiet"],
                 ["corpus", "synth", "--out", tmp_path / "corpus"]):
        line = tsel_cli.refused(*argv)
        assert "disk full; no space left on the device; free space or write to another disk" in line, argv
        assert "--resume" not in line and line.endswith("then run it again"), line
    monkeypatch.undo()
    out = tmp_path / "ds"
    calls = {"n": 0}
    real = writer._stack_padded

    def full_at_second_shard(*a, **k):
        calls["n"] += 1
        if calls["n"] > 4:  # 4 label arrays per shard: the second shard's first
            _no_space()
        return real(*a, **k)

    monkeypatch.setattr(writer, "_stack_padded", full_at_second_shard)
    line = tsel_cli.refused("generate", *DEMO_RUN, "--corpus-dir", demo_corpus, "--out", out, "--workers", "1",
                            "--quiet")
    assert line.endswith("disk full; no space left on the device; free space, then rerun with --resume: finished "
                         "shards are kept"), line
    calls["n"] = 4  # the disk is still full when render writes the second shard again
    line = tsel_cli.refused("render", out, "--workers", "1", "--quiet")
    assert line.endswith("then run it again: finished shards are kept") and "--resume" not in line, line


def test_a_shard_whose_close_fails_is_a_failed_write(dataset, tsel_cli, tmp_path, monkeypatch):
    pytest.importorskip("pyarrow")
    from tsel_data.export import hf

    def flush_fails(self):  # pyarrow flushes the last row group on close: the disk fills there
        raise OSError("Error writing bytes to file. Detail: [errno 28] No space left on device")

    monkeypatch.setattr(hf._ParquetShard, "close", flush_fails)
    line = tsel_cli.refused("export", "hf", dataset, "--out", tmp_path / "hf", "--quiet")
    assert "cannot write" in line and "00000.parquet: disk full" in line, line
    assert not [n for _, _, ns in os.walk(tmp_path / "hf") for n in ns if ".tmp-" in n]


def test_a_tar_shard_that_fills_the_disk_is_a_failed_write(dataset, tsel_cli, tmp_path, monkeypatch):
    from tsel_data.export import webdataset

    calls = {"n": 0}
    real = os.writev

    def full_at_the_third_scene(fd, parts):  # a tar goes out one scene per writev
        calls["n"] += 1
        if calls["n"] >= 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, parts)

    monkeypatch.setattr(webdataset.os, "writev", full_at_the_third_scene)
    line = tsel_cli.refused("export", "webdataset", dataset, "--out", tmp_path / "wds", "--quiet")
    assert "cannot write" in line and "000000.tar: disk full" in line, line
    assert not [n for _, _, ns in os.walk(tmp_path / "wds") for n in ns if ".tmp-" in n or n.endswith(".tar")]


def test_libsndfile_system_error_on_a_full_disk_says_disk_full(dataset, tsel_cli, tmp_path, monkeypatch):
    def system_error(*a, **k):
        raise sf.LibsndfileError(2, "Error writing: ")  # libsndfile's SF_ERR_SYSTEM: "System error."

    real_statvfs = os.statvfs

    def nearly_full(path):
        st = real_statvfs(path)
        return os.statvfs_result((st.f_bsize, st.f_frsize, st.f_blocks, 3, 3, *tuple(st)[5:]))

    monkeypatch.setattr(sf, "write", system_error)
    monkeypatch.setattr(os, "statvfs", nearly_full)
    monkeypatch.chdir(tmp_path)
    line = tsel_cli.refused("inspect", dataset, "test/0", "--wav", tmp_path / "x.wav", "--no-stems")
    assert "cannot write x.wav: disk full" in line and "System error" not in line, line
    assert not os.path.exists(tmp_path / "x.wav")


def test_libsndfile_system_error_into_a_missing_folder_says_so(dataset, tsel_cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    real = atomic.atomic_output

    def folder_gone(path, what=None):  # the folder vanished between the claim and the write
        os.rmdir(os.path.dirname(os.path.abspath(path)))
        return real(path, what)

    monkeypatch.setattr(atomic, "atomic_output", folder_gone)
    import tsel_data.corpus.audio as audio  # save_wav's own name for it

    monkeypatch.setattr(audio, "atomic_output", folder_gone)
    os.mkdir("gone")
    line = tsel_cli.refused("inspect", dataset, "test/0", "--wav", "gone/x.wav", "--no-stems")
    assert "the folder gone does not exist; create it or write elsewhere" in line, line


def test_a_bank_the_disk_cannot_hold_is_refused_before_writing(tsel_cli, tmp_path, monkeypatch):
    import shutil

    from tsel_data.banks import native

    free = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(native.shutil, "disk_usage", lambda p: free._replace(free=4096))
    out = tmp_path / "b.h5"
    line = tsel_cli.refused("bank", "build", "--out", out, "--rooms", "1", "--step", "60", "--distances", "1.0",
                            "--heights", "0", "--rir-seconds", "0.05")
    assert "the bank takes about" in line and "MB free; free space or write to another disk" in line, line
    make_tau_db(tmp_path / "tau")
    line = tsel_cli.refused("bank", "import", "tau", "--src", tmp_path / "tau", "--out", out)
    assert "the bank takes about" in line, line
    assert not [n for n in os.listdir(tmp_path) if n.startswith("b.h5")]


# --- §4: messages that point the right way -------------------------------------------------------


def test_out_as_a_dangling_link_is_named_a_link(demo_corpus, dataset, tsel_cli, tmp_path):
    link = tmp_path / "out"
    os.symlink(tmp_path / "nowhere" / "x", link)
    for argv in (["generate", *DEMO_RUN, "--corpus-dir", demo_corpus, "--out", link, "--quiet"],
                 ["plan", *DEMO_RUN, "--corpus-dir", demo_corpus, "--out", link],
                 ["export", "dcase", dataset, "--out", link],
                 ["inspect", dataset, "test/0", "--wav", link, "--no-stems"]):
        line = tsel_cli.refused(*argv)
        assert "is a symbolic link to" in line and "which does not exist" in line, line
        assert "--resume" not in line and "File exists" not in line, line


def test_a_manifest_link_that_loops_is_not_called_missing(tsel_cli, tmp_path, monkeypatch):
    corpus = _corpus(tmp_path / "corpus", monkeypatch)
    (corpus / "train.csv").rename(corpus / "real.csv")
    os.symlink("other.csv", corpus / "train.csv")
    os.symlink("train.csv", corpus / "other.csv")
    line = tsel_cli.refused("check", *_config(tmp_path, corpus))
    assert "train.csv is a symbolic link that loops" in line and "other.csv" in line, line
    assert "not found" not in line, line


def test_a_huge_caption_gets_no_quoting_advice(tsel_cli, tmp_path, monkeypatch):
    corpus = _corpus(tmp_path / "corpus", monkeypatch)
    rows = (corpus / "train.csv").read_text().splitlines()
    rows[2] = f'1,clip1,0,"{"a dog barks " * 17000}"'  # 204,000 characters, quoted as it should be
    (corpus / "train.csv").write_text("\n".join(rows) + "\n")
    line = tsel_cli.refused("check", *_config(tmp_path, corpus))
    assert "train.csv:3: a field holds more than 131,072 characters" in line, line
    assert "quote" not in line, line


def test_a_column_given_twice_is_refused(tsel_cli, tmp_path, monkeypatch):
    corpus = _corpus(tmp_path / "corpus", monkeypatch)
    rows = (corpus / "train.csv").read_text().splitlines()
    (corpus / "train.csv").write_text("\n".join([rows[0] + ",caption"] + [r + ",another caption" for r in rows[1:]])
                                      + "\n")
    line = tsel_cli.refused("check", *_config(tmp_path, corpus))
    assert "train.csv:1: column 'caption' appears twice (columns 4 and 5)" in line, line
    jsonl = tmp_path / "m.jsonl"  # JSON keeps the last of two keys without a word
    jsonl.write_text('{"path": "corpus/audio/clip0.wav", "caption": "a dog", "caption": "a cat", "split": "train"}\n')
    line = tsel_cli.refused("check", "--preset", "demo", "--manifest", jsonl, "--no-plan")
    assert "m.jsonl:1: key 'caption' appears twice in one object" in line, line


# --- §5: never a hang, one line whatever a name holds ---------------------------------------------------


def test_a_fifo_given_as_bank_is_refused_not_read(tsel_cli, tmp_path):
    fifo = tmp_path / "bank.h5"
    os.mkfifo(fifo)
    # a writer that answers a reader with junk, so reading the pipe ends instead of waiting
    feed = threading.Thread(target=lambda: open(fifo, "wb").write(b"junk"), daemon=True)
    feed.start()
    try:
        assert "bank.h5 is not a regular file: it is a FIFO (a named pipe)" in tsel_cli.refused("bank", "info", fifo)
        assert "is not a regular file" in tsel_cli.refused("check", "--preset", "demo-moving", "--bank", fifo,
                                                           "--split", "train=2", "--no-plan")
    finally:
        os.close(os.open(fifo, os.O_RDONLY | os.O_NONBLOCK))  # lets the writer go
        feed.join()


def _session(sid: int) -> list[int]:
    """Processes of session ``sid`` still alive (zombies are not)."""
    alive = []
    for name in os.listdir("/proc"):
        try:
            fields = open(f"/proc/{name}/stat").read().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            alive.append(int(name))
    return alive


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads the process table from /proc")
def test_sighup_to_render_ends_its_pool_workers(small_config, tmp_path):
    from tsel_data.job.pipeline import plan_dataset

    out = str(tmp_path / "ds")
    plan_dataset(small_config(splits={"train": 16, "val": 0, "test": 0}), out)
    p = subprocess.Popen([sys.executable, "-m", "tsel_data.cli", "render", out, "--workers", "2", "--quiet"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    while len(_session(p.pid)) < 3 and p.poll() is None:  # the main process and its two workers
        time.sleep(0.01)
    workers = [pid for pid in _session(p.pid) if pid != p.pid]
    os.kill(p.pid, signal.SIGHUP)  # the terminal went away: the main process alone gets it
    err = p.communicate()[1]
    assert p.returncode == 129 and "Traceback" not in err, err
    assert not [w for w in workers if w in _session(p.pid)], "pool workers outlived tsel render"


def test_a_name_with_control_characters_prints_on_one_line(tsel_cli, tmp_path, monkeypatch):
    corpus = _corpus(tmp_path / "corpus", monkeypatch)
    rows = (corpus / "train.csv").read_text().splitlines()
    rows[2] = '1,"clip\nnext\x1b[31m",0,a dog barks'  # no such audio file: the message names it
    (corpus / "train.csv").write_text("\n".join(rows) + "\n")
    code, _, err = tsel_cli.run("check", *_config(tmp_path, corpus))
    errors = [x for x in err.splitlines() if x.startswith("error:")]
    assert code == 2 and len(errors) == 1 and len(err.splitlines()) == len([x for x in err.splitlines() if x]), err
    assert "clip\\nnext\\x1b[31m" in errors[0] and "\x1b" not in err, err


# --- issue 26 §3: paths that stay private -----------------------------------------------------------------


def test_error_lines_name_files_relative_to_the_working_folder_once(tsel_cli, tmp_path, monkeypatch):
    corpus = _corpus(tmp_path / "corpus", monkeypatch)
    (corpus / "audio" / "clip1.wav").write_bytes(b"RIFF not audio")
    line = tsel_cli.refused("check", *_config(tmp_path, tmp_path / "corpus"))  # absolute paths given
    assert str(tmp_path) not in line, line
    assert "unreadable audio corpus/audio/clip1.wav" in line and line.count("clip1.wav") == 1, line


@pytest.mark.parametrize("fmt", ["dcase", "webdataset", "hf", "lhotse", "card"])
def test_no_export_names_a_folder_of_this_machine(dataset, tsel_cli, tmp_path, fmt):
    if fmt == "hf":
        pytest.importorskip("pyarrow")
    out = tmp_path / "exp"
    tsel_cli.ok("export", fmt, os.path.abspath(dataset), "--out", out.absolute(), "--quiet")
    machine = [os.path.dirname(os.path.abspath(dataset)).encode(), str(tmp_path).encode()]
    for d, _, names in os.walk(out):
        for n in names:
            data = open(os.path.join(d, n), "rb").read()
            assert not any(m in data for m in machine), os.path.join(d, n)
    if fmt == "dcase":
        assert "source" not in json.load(open(out / "classes.json"))


def test_eval_dcase_names_the_missing_file_whole(dataset, tsel_cli, tmp_path):
    """The example file name of a missing DCASE prediction is quoted whole, not 'id'.csv."""
    (tmp_path / "pred").mkdir()
    (tmp_path / "pred" / "fold1_test-000000.csv").write_text("")
    line = tsel_cli.refused("eval", "--dcase", "--pred", tmp_path / "pred", dataset, "--split", "test")
    assert "1 of 2 scenes of split 'test' have no prediction file, e.g. 'test-000001.csv';" in line, line


@pytest.mark.parametrize("preset, splits", [("demo", "train, val, test"), ("demo-recorded", "train, test")])
def test_a_split_the_config_has_not_is_named_with_those_it_has(tsel_cli, preset, splits, tmp_path):
    for command in (["check"], ["generate", "--out", tmp_path / "out"]):
        line = tsel_cli.refused(*command, "--preset", preset, "--split", "train=2", "--split", "valid=6")
        assert line == (f"error: --split valid=6: there is no split 'valid'; the splits are {splits} (to make a new "
                        f"one, add a [splits.valid] table to the config)"), line
    assert not (tmp_path / "out").exists()
    # a split the config's other layers define is one: --set makes it, --manifest serves every split named
    from tsel_data.cli.options import load
    made = load(preset, None, None, ["valid=6"], None, None, ["splits.valid.manifest='val.csv'"])
    assert made.splits["valid"].count == 6
    shared = load(preset, None, str(tmp_path), ["valid=6"], None, None, [], manifest=str(tmp_path / "m.csv"))
    assert shared.splits["valid"].manifest == "m.csv"


def test_a_clip_in_a_format_libsndfile_cannot_read_says_so(tsel_cli, tmp_path, monkeypatch):
    """An .m4a (AAC) clip is named with what to do, not only libsndfile's 'Format not recognised'."""
    corpus = _corpus(tmp_path / "corpus", monkeypatch)
    for i in range(3):
        (corpus / "audio" / f"clip{i}.wav").rename(corpus / "audio" / f"clip{i}.m4a")
    (corpus / "audio" / "clip1.m4a").write_bytes(b"\x00\x00\x00\x20ftypM4A \x00\x00\x02\x00" + bytes(64))
    line = tsel_cli.refused("check", *_config(tmp_path, corpus), "--set", "corpus.audio_template='{youtube_id}.m4a'")
    assert "unreadable audio corpus/audio/clip1.m4a: " in line, line
    assert ("; libsndfile does not read .m4a files (it reads WAV, FLAC, OGG Vorbis/Opus, MP3, AIFF and a "
                         "few more): convert the clips, e.g. to FLAC with ffmpeg, and name them in "
                         "corpus.audio_template") in line, line
    from tsel_data.corpus.audio import load_clip
    from tsel_data.errors import AudioError
    with pytest.raises(AudioError, match=r"clip1.m4a: .*; libsndfile does not read .m4a files"):
        load_clip(str(corpus / "audio" / "clip1.m4a"), 16000, 1.0)
