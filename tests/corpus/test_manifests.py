"""Manifest readers: AudioCaps, Clotho, WavCaps, plain CSV/JSONL, detection, errors."""
from __future__ import annotations

import csv
import gc
import io
import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from support import datasets as datasetfixture
from tsel_data.corpus.clip import Clip
from tsel_data.errors import ManifestError
from tsel_data.corpus.manifests import (FORMATS, detect_format, missing_audio, read_audiocaps, read_clotho,
                                        read_manifest, read_plain, read_wavcaps)

from support import REPO
SHARED_AUDIOCAPS = Path(datasetfixture.SHARED_AUDIOCAPS)
AC_HEADER = ["audiocap_id", "youtube_id", "start_time", "caption"]
UNICODE = "café — ünïcode 雨の音 🐦"


def write(path: Path, text: str) -> Path:
    path.write_bytes(text.encode("utf-8"))
    return path


def write_csv(path: Path, rows) -> Path:
    with open(path, "w", encoding="utf-8", newline="") as f:
        csv.writer(f).writerows(rows)
    return path


def raises(fn, *args, match_row: int | None = None, **kw) -> str:
    """Call fn, expect a one-line ManifestError naming the file (and row); return it."""
    path = Path(args[0])
    with pytest.raises(ManifestError) as ei:
        fn(*args, **kw)
    msg = str(ei.value)
    assert "\n" not in msg
    assert path.name in msg, msg
    if match_row is not None:
        assert f"{path.name}:{match_row}:" in msg, msg
    return msg


# ---------------------------------------------------------------- AudioCaps


@pytest.fixture
def val_csv(tmp_path) -> Path:
    """Two clips of 5 captions, interleaved as in the official val/test files, + 1 single."""
    rows = [AC_HEADER]
    for k in range(5):
        rows.append([str(100 + k), "abcDEF_-123", "30", f"dog barks, take {k}"])
        rows.append([str(200 + k), "zzz", "0", f"rain {k}"])
    rows.append(["300", "uni", "120", UNICODE])
    return write_csv(tmp_path / "val.csv", rows)


def test_audiocaps_groups_captions_in_file_order(val_csv):
    clips = read_audiocaps(val_csv)
    assert [c.id for c in clips] == ["abcDEF_-123_30", "zzz_0", "uni_120"]
    a, b, u = clips
    assert a.captions == tuple(f"dog barks, take {k}" for k in range(5))  # quoted commas
    assert b.captions == tuple(f"rain {k}" for k in range(5))
    assert u.captions == (UNICODE,)
    assert a.meta == {"youtube_id": "abcDEF_-123", "start_time": 30.0,
                      "audiocap_ids": ["100", "101", "102", "103", "104"]}
    assert a.offset == 0.0 and a.split == "val"  # split from the file name
    # origin = first row's physical line, header = line 1
    assert [c.origin for c in clips] == [f"{val_csv}:2", f"{val_csv}:3", f"{val_csv}:12"]
    assert a.audio == os.path.join(str(val_csv.parent), "abcDEF_-123.wav")


@pytest.mark.parametrize("template, expected", [
    ("{youtube_id}.wav", "abcDEF_-123.wav"),
    ("Y{youtube_id}.wav", "YabcDEF_-123.wav"),
    ("{audiocap_id}.wav", "100.wav"),  # the clip's first row
    ("{youtube_id}_{start_time}.flac", "abcDEF_-123_30.flac"),
    ("sub/{start_time}/{audiocap_id}-{youtube_id}.wav", "sub/30/100-abcDEF_-123.wav"),
])
def test_audiocaps_template_fields(val_csv, tmp_path, template, expected):
    audio_dir = tmp_path / "audio"
    clip = read_audiocaps(val_csv, audio_dir=audio_dir, template=template)[0]
    assert clip.audio == str(audio_dir / expected)


@pytest.mark.parametrize("template, bad", [
    ("{ytid}.wav", "{ytid}"), ("{}.wav", "{}"), ("{0}.wav", "{0}"), ("{id}.wav", "{id}")])
def test_audiocaps_unknown_template_field(val_csv, template, bad):
    msg = raises(read_audiocaps, val_csv, template=template)
    assert bad in msg
    for allowed in ("{youtube_id}", "{audiocap_id}", "{start_time}"):
        assert allowed in msg


def test_audiocaps_bad_template_syntax(val_csv):
    raises(read_audiocaps, val_csv, template="{youtube_id.wav")
    raises(read_audiocaps, val_csv, template="{start_time:d}.wav")


def test_audiocaps_split_argument_and_no_split(tmp_path):
    p = write_csv(tmp_path / "captions.csv", [AC_HEADER, ["1", "a", "0", "x"]])
    assert read_audiocaps(p)[0].split is None
    assert read_audiocaps(p, split="train")[0].split == "train"


def test_audiocaps_multiline_caption_keeps_physical_line_numbers(tmp_path):
    p = write_csv(tmp_path / "ac.csv", [AC_HEADER, ["1", "a", "0", "two\nlines\r\nthree"],
                                        ["2", "b", "0", "ok"], ["3", "c", "0", ""]])
    clips_text = p.read_text(encoding="utf-8")
    assert clips_text.count("\n") == 6  # header, 3 lines of row a, b, c
    raises(read_audiocaps, p, match_row=6)  # the empty caption is on line 6
    write_csv(p, [AC_HEADER, ["1", "a", "0", "two\nlines"], ["2", "b", "0", "ok"]])
    assert [c.origin.rsplit(":", 1)[1] for c in read_audiocaps(p)] == ["2", "4"]


def test_audiocaps_bom_crlf_and_blank_lines(tmp_path):
    p = tmp_path / "ac.csv"
    p.write_bytes("\ufeffaudiocap_id,youtube_id,start_time,caption\r\n\r\n"
                  "1,a,0,\"x, y\"\r\n\r\n".encode("utf-8"))
    (clip,) = read_audiocaps(p)
    assert clip.captions == ("x, y",) and clip.origin.endswith(":3")


# Errors: one parametrised table, each must name file and row.
AC_ERRORS = {
    "wrong field count": ("1,a,0,x\n2,b,0,unquoted, comma\n", 3, "4"),
    "too few fields": ("1,a,0,x\n2,b,0\n", 3, "fields"),
    "empty youtube_id": ("1,a,0,x\n2, ,0,y\n", 3, "youtube_id"),
    "non-numeric start_time": ("1,a,0,x\n2,b,thirty,y\n", 3, "start_time"),
    "negative start_time": ("1,a,-5,y\n", 2, "start_time"),
    "nan start_time": ("1,a,nan,y\n", 2, "start_time"),
    "exponent start_time": ("1,a,1e3,y\n", 2, "start_time"),
    "underscore start_time": ("1,a,1_0,y\n", 2, "start_time"),
    "non-ascii digit start_time": ("1,a,\u0663,y\n", 2, "start_time"),
    "empty caption": ("1,a,0,x\n2,b,0,\"  \"\n", 3, "empty caption"),
    "empty audiocap_id": ("1,a,0,x\n,b,0,y\n", 3, "audiocap_id"),
    "unterminated quote": ("1,a,0,x\n2,b,0,\"never closed\n3,c,0,z\n", 3, "quot"),
}


@pytest.mark.parametrize("case", AC_ERRORS)
def test_audiocaps_row_errors(tmp_path, case):
    body, row, word = AC_ERRORS[case]
    p = write(tmp_path / "train.csv", ",".join(AC_HEADER) + "\n" + body)
    msg = raises(read_audiocaps, p, match_row=row)
    assert word in msg


def test_audiocaps_missing_column_lists_found_and_required(tmp_path):
    p = write(tmp_path / "ac.csv", "audiocap_id,youtube_id,caption\n1,a,x\n")
    msg = raises(read_audiocaps, p, match_row=1)
    assert "start_time" in msg and "found: audiocap_id,youtube_id,caption" in msg
    assert "required: audiocap_id,youtube_id,start_time,caption" in msg


def test_missing_file_is_named(tmp_path):
    p = tmp_path / "nope" / "train.csv"
    for reader in (read_audiocaps, read_clotho, read_wavcaps, read_plain, read_manifest):
        msg = raises(reader, p)
        assert "not found" in msg and str(p) in msg


def test_directory_instead_of_file(tmp_path):
    raises(read_audiocaps, tmp_path)


def test_not_utf8_names_line_and_byte_offset(tmp_path):
    head = b"audiocap_id,youtube_id,start_time,caption\n1,a,0,ok\n"
    p = tmp_path / "latin.csv"
    p.write_bytes(head + "2,b,0,caf\u00e9\n".encode("latin-1"))
    msg = raises(read_audiocaps, p, match_row=3)
    assert f"byte offset {len(head) + 9}" in msg and "UTF-8" in msg
    # every reader goes through the same decoding
    q = tmp_path / "latin.jsonl"
    q.write_bytes(b'{"path": "a.wav", "caption": "ok"}\n{"path": "b.wav", "caption": "\xe9"}\n')
    raises(read_plain, q, match_row=2)


@pytest.mark.parametrize("text", ["", "audiocap_id,youtube_id,start_time,caption\n",
                                  "audiocap_id,youtube_id,start_time,caption\n\n\n", "\n\n"])
def test_empty_audiocaps(tmp_path, text):
    msg = raises(read_audiocaps, write(tmp_path / "e.csv", text))
    assert "empty" in msg


def test_gc_state_restored(tmp_path, val_csv):
    assert gc.isenabled()
    read_audiocaps(val_csv)
    assert gc.isenabled()
    with pytest.raises(ManifestError):
        read_audiocaps(write(tmp_path / "bad.csv", "x\n"))
    assert gc.isenabled()


@pytest.mark.skipif(not SHARED_AUDIOCAPS.is_dir(), reason="../shared/audiocaps not present")
def test_real_audiocaps_counts():
    clips = {s: read_audiocaps(SHARED_AUDIOCAPS / f"{s}.csv") for s in ("train", "val", "test")}
    expected = {"train": (49838, 1), "val": (495, 5), "test": (975, 5)}
    for s, (n_clips, n_caps) in expected.items():
        assert len(clips[s]) == n_clips
        assert {len(c.captions) for c in clips[s]} == {n_caps}
        assert {c.split for c in clips[s]} == {s}
        assert len({c.id for c in clips[s]}) == n_clips
    assert sum(len(c.captions) for c in clips["train"]) == 49838
    assert sum(len(c.captions) for c in clips["val"]) == 2475
    assert sum(len(c.captions) for c in clips["test"]) == 4875


# ---------------------------------------------------------------- Clotho

CLOTHO_HEADER = ["file_name"] + [f"caption_{k}" for k in range(1, 6)]


def test_clotho_parses_quoted_names_and_five_captions(tmp_path):
    rows = [CLOTHO_HEADER,
            ["Crowd, int, echoes.wav"] + [f"people talk, {k}" for k in range(5)],
            ["rain.wav", UNICODE, "b", "c", "d", "e"]]
    p = write_csv(tmp_path / "clotho_captions_development.csv", rows)
    a, b = read_clotho(p, audio_dir=tmp_path / "dev")
    assert a.id == "Crowd, int, echoes.wav"
    assert a.audio == str(tmp_path / "dev" / "Crowd, int, echoes.wav")
    assert a.captions == tuple(f"people talk, {k}" for k in range(5))
    assert b.captions[0] == UNICODE and len(b.captions) == 5
    assert a.split == b.split == "train"  # development -> train
    assert b.origin == f"{p}:3"


@pytest.mark.parametrize("name, split", [
    ("clotho_captions_development.csv", "train"), ("clotho_captions_validation.csv", "val"),
    ("clotho_captions_evaluation.csv", "test"), ("clotho_captions.csv", None),
    ("train_vs_test.csv", None)])
def test_split_from_file_name(tmp_path, name, split):
    p = write(tmp_path / name, "file_name,caption_1\nx.wav,a\n")
    assert read_clotho(p)[0].split == split
    assert read_clotho(p, split="other")[0].split == "other"
    # plain manifests never guess a split from their name
    q = write(tmp_path / ("plain_" + name), "path,caption\nx.wav,a\n")
    assert read_plain(q)[0].split is None


def test_clotho_caption_columns_in_numeric_order(tmp_path):
    p = write(tmp_path / "c.csv", "caption_2,file_name,caption_10,caption_1\nB,x.wav,J,A\n")
    assert read_clotho(p)[0].captions == ("A", "B", "J")


def test_clotho_errors(tmp_path):
    five = ["a", "b", "c", "d", "e"]
    p = write_csv(tmp_path / "clotho.csv", [CLOTHO_HEADER, ["x.wav"] + five, ["y.wav"] + five,
                                            ["x.wav"] + five])
    msg = raises(read_clotho, p, match_row=4)
    assert "duplicate" in msg and "line 2" in msg  # names both rows
    write_csv(p, [CLOTHO_HEADER, ["x.wav"] + five, ["y.wav", "a", "b", "", "d", "e"]])
    assert "caption_3" in raises(read_clotho, p, match_row=3)
    write_csv(p, [CLOTHO_HEADER, ["", *five]])
    assert "file_name" in raises(read_clotho, p, match_row=2)
    write_csv(p, [["file", "caption"], ["x.wav", "a"]])
    assert "file_name" in raises(read_clotho, p, match_row=1)
    write_csv(p, [CLOTHO_HEADER])
    raises(read_clotho, p)


# ---------------------------------------------------------------- WavCaps


def test_wavcaps_real_collection_shapes(tmp_path):
    doc = {"num_captions_per_audio": 1, "data": [
        # AudioSet_SL: id with extension, placeholder audio
        {"id": "Y---1_cCGK4M.wav", "caption": "Wind blows, a man speaks.", "audio": "wav_path",
         "duration": 10.0},
        # FreeSound: numeric id string, many extra keys
        {"id": "180913", "file_name": "UK Mello.wav", "tags": ["x"], "author": "a",
         "description": "d", "href": "/h/", "download_link": "l", "caption": UNICODE,
         "audio": "wav_path", "duration": 3.2},
        # BBC: category string
        {"description": "d", "category": "['Nature']", "caption": "A bug buzzes.",
         "id": "NHU05051026", "duration": 88.8, "audio": "wav_path", "download_link": "l"},
        # id as a JSON number, a real relative audio path
        {"id": 2219, "caption": "An airplane lands.", "audio": "sb/2219.wav"},
    ]}
    p = write(tmp_path / "as_final.json", json.dumps(doc, ensure_ascii=False))
    clips = read_wavcaps(p, audio_dir=tmp_path / "flac")
    assert [c.id for c in clips] == ["Y---1_cCGK4M", "180913", "NHU05051026", "2219"]
    assert clips[0].audio == str(tmp_path / "flac" / "Y---1_cCGK4M.flac")
    assert clips[0].meta == {"raw_id": "Y---1_cCGK4M.wav", "duration": 10.0}
    assert clips[1].captions == (UNICODE,)
    assert clips[3].audio == str(tmp_path / "flac" / "sb" / "2219.wav")
    assert [c.origin for c in clips] == [f"{p}:{n}" for n in range(1, 5)]
    assert read_wavcaps(p, template="{raw_id}")[0].audio == str(tmp_path / "Y---1_cCGK4M.wav")
    assert "{id}" in raises(read_wavcaps, p, template="{youtube_id}.flac")


def test_wavcaps_bare_list_and_caption_lists(tmp_path):
    p = write(tmp_path / "sb_final.json", json.dumps(
        [{"id": "1", "captions": ["a, b", "c"]}, {"id": "2", "caption": "d"}]))
    clips = read_wavcaps(p)
    assert [c.captions for c in clips] == [("a, b", "c"), ("d",)]


@pytest.mark.parametrize("doc, row, word", [
    ({"data": [{"id": "a", "caption": "x"}, {"id": "a.wav", "caption": "y"}]}, 2, "duplicate"),
    ({"data": [{"id": "a", "caption": "x"}, {"caption": "y"}]}, 2, "id"),
    ({"data": [{"id": "a", "caption": "x"}, {"id": "b", "caption": " "}]}, 2, "empty caption"),
    ({"data": [{"id": "a", "caption": "x"}, {"id": "b"}]}, 2, "caption"),
    ({"data": [{"id": "a", "caption": "x"}, ["b", "y"]]}, 2, "object"),
    ({"data": [{"id": "a", "caption": 3}]}, 1, "string"),
])
def test_wavcaps_entry_errors(tmp_path, doc, row, word):
    msg = raises(read_wavcaps, write(tmp_path / "w.json", json.dumps(doc)), match_row=row)
    assert word in msg
    if word == "duplicate":
        assert "entry 1" in msg and "entry 2" in msg


def test_wavcaps_file_errors(tmp_path):
    p = write(tmp_path / "w.json", '{"data": [\n{"id": "a", "caption": "x"},\n{"id": }]}')
    assert "line 3" in raises(read_wavcaps, p, match_row=3)
    write(p, json.dumps({"rows": []}))
    assert "'rows'" in raises(read_wavcaps, p)
    write(p, json.dumps({"data": []}))
    assert "empty" in raises(read_wavcaps, p)


# ---------------------------------------------------------------- plain


def test_plain_csv_grouping_split_and_paths(tmp_path):
    rows = [["path", "caption", "id", "split"],
            ["a/bell.wav", "a bell, ringing", "bell", "train"],
            ["/abs/siren.wav", UNICODE, "", ""],
            ["a/bell.wav", "ding", "bell", "train"]]
    p = write_csv(tmp_path / "mine.csv", rows)
    bell, siren = read_plain(p, split="val")
    assert bell.id == "bell" and bell.captions == ("a bell, ringing", "ding")
    assert bell.audio == str(tmp_path / "a" / "bell.wav") and bell.split == "train"
    assert siren.id == "/abs/siren.wav" and siren.audio == "/abs/siren.wav"
    assert siren.split == "val"  # empty split cell -> the argument
    assert bell.origin == f"{p}:2" and siren.origin == f"{p}:3"


def test_plain_without_id_groups_by_path(tmp_path):
    p = write_csv(tmp_path / "p.csv", [["caption", "path"], ["x", "../up.wav"], ["y", "../up.wav"]])
    (clip,) = read_plain(p, audio_dir=tmp_path / "d")
    assert clip.id == "../up.wav" and clip.captions == ("x", "y")
    assert clip.audio == str(tmp_path / "up.wav")  # normalised


def test_plain_jsonl(tmp_path):
    lines = [{"path": "a.wav", "caption": "one, two", "id": 7},
             {"path": "a.wav", "caption": ["three", UNICODE], "id": "7", "split": "test"},
             {"path": "b.wav", "captions": ["b"]}]
    lines[1]["split"] = None  # null split = not given
    text = "\n".join(json.dumps(x, ensure_ascii=False) for x in lines) + "\n\n"
    p = write(tmp_path / "m.jsonl", text)
    a, b = read_plain(p)
    assert a.id == "7" and a.captions == ("one, two", "three", UNICODE)
    assert b.id == "b.wav" and b.origin == f"{p}:3"
    # content sniffing for other extensions
    assert [c.id for c in read_plain(write(tmp_path / "m.txt", text))] == ["7", "b.wav"]


@pytest.mark.parametrize("name, text, row, word", [
    ("p.csv", "path,caption,id\na.wav,x,1\nb.wav,y,1\n", 3, "line 2"),
    ("p.csv", "path,caption,split\na.wav,x,train\na.wav,y,test\n", 3, "split"),
    ("p.csv", "path,caption\na.wav,x\n ,y\n", 3, "path"),
    ("p.csv", "path,caption\na.wav,x\nb.wav,\n", 3, "empty caption"),
    ("p.csv", "path,text\na.wav,x\n", 1, "caption"),
    ("p.jsonl", '{"path": "a.wav", "caption": "x"}\n{"path": "b.wav", caption: 1}\n', 2, "JSON"),
    ("p.jsonl", '{"path": "a.wav", "caption": "x"}\n\n["b.wav", "y"]\n', 3, "object"),
    ("p.jsonl", '{"path": "a.wav"}\n', 1, "caption"),
    ("p.jsonl", '{"path": "a.wav", "caption": []}\n', 1, "empty caption"),
    ("p.jsonl", '{"path": "a.wav", "caption": ["x", 2]}\n', 1, "string"),
])
def test_plain_errors(tmp_path, name, text, row, word):
    msg = raises(read_plain, write(tmp_path / name, text), match_row=row)
    assert word in msg


def test_plain_empty(tmp_path):
    raises(read_plain, write(tmp_path / "p.jsonl", "\n \n"))
    raises(read_plain, write(tmp_path / "p.csv", "path,caption\n"))


# ---------------------------------------------------------------- dispatcher


def test_formats_tuple():
    assert FORMATS == ("audiocaps", "clotho", "wavcaps", "plain")


@pytest.mark.parametrize("name, text, fmt", [
    ("a.csv", "audiocap_id,youtube_id,start_time,caption\n1,a,0,x\n", "audiocaps"),
    ("a.txt", "AudioCap_ID, YouTube_ID, Start_Time, Caption\n1,a,0,x\n", "audiocaps"),
    ("c.csv", "file_name,caption_1,caption_2\nx.wav,a,b\n", "clotho"),
    ("p.csv", "path,caption\nx.wav,a\n", "plain"),
    ("p.tsvish", "id,path,caption,split\n1,x.wav,a,train\n", "plain"),
    ("w.json", '{"data": [{"id": "1", "caption": "a"}]}', "wavcaps"),
    ("w.data", '{"data": [{"id": "1", "caption": "a"}]}', "wavcaps"),
    ("w.data2", '{\n "data": [{"id": "1", "caption": "a"}]\n}', "wavcaps"),
    ("w.list", '[{"id": "1", "caption": "a"}]', "wavcaps"),
    ("p.jsonl", '{"path": "x.wav", "caption": "a"}\n', "plain"),
    ("p.log", '{"path": "x.wav", "caption": "a"}\n', "plain"),
])
def test_auto_detection(tmp_path, name, text, fmt):
    p = write(tmp_path / name, text)
    assert detect_format(p) == fmt
    clips = read_manifest(p)
    assert len(clips) == 1 and isinstance(clips[0], Clip)


def test_detection_failure_and_bad_arguments(tmp_path):
    p = write(tmp_path / "x.csv", "name,text\na,b\n")
    assert "known headers" in raises(read_manifest, p, match_row=1)
    ac = write(tmp_path / "ac.csv", "audiocap_id,youtube_id,start_time,caption\n1,a,0,x\n")
    assert "clotho" in raises(read_manifest, ac, format="nope")
    msg = raises(read_manifest, ac, format="clotho", template="{x}")
    assert "template" in msg and "split" in msg
    (clip,) = read_manifest(ac, template="Y{youtube_id}.wav", split="train",
                            audio_dir=tmp_path / "au")
    assert clip.audio == str(tmp_path / "au" / "Ya.wav") and clip.split == "train"


def test_example_manifests_in_repo():
    """Every example in manifests/ is detected as its format and parses."""
    examples = {"audiocaps.csv": "audiocaps", "clotho.csv": "clotho",
                "wavcaps.json": "wavcaps", "plain.csv": "plain", "plain.jsonl": "plain"}
    for name, fmt in examples.items():
        path = REPO / "manifests" / name
        assert detect_format(path) == fmt
        clips = read_manifest(path)
        assert clips and all(c.captions and all(c.captions) for c in clips)
        assert len({c.id for c in clips}) == len(clips)
        for c in clips:
            assert Clip.from_dict(json.loads(json.dumps(c.to_dict()))) == c


# ---------------------------------------------------------------- missing_audio


def test_missing_audio(tmp_path):
    (tmp_path / "here.wav").write_bytes(b"")
    (tmp_path / "adir.wav").mkdir()
    clips = [Clip(id=str(i), audio=str(tmp_path / n), captions=("x",))
             for i, n in enumerate(["here.wav", "gone.wav", "here.wav", "gone.wav", "adir.wav"])]
    assert [c.id for c in missing_audio(clips)] == ["1", "3", "4"]
    assert missing_audio([]) == []


# ---------------------------------------------------------------- properties

# Any text csv.writer can write, except lone surrogates (not encodable as UTF-8).
caption_text = st.text(st.characters(blacklist_categories=("Cs",)), min_size=1,
                       max_size=40).filter(lambda s: s.strip())
tricky = st.sampled_from(['a, b', '"quoted"', 'line\nbreak', 'cr\rlf\r\n', ' ', "é—ü",
                          "\u2028", "\x00"])
captions = st.lists(st.one_of(caption_text, st.builds(lambda a, b: a + b, caption_text, tricky)),
                    min_size=1, max_size=5)
PROPERTY = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _physical_line_starts(rows) -> list[int]:
    """Line (1-based, universal newlines) on which each row's record starts."""
    buf = io.StringIO()
    w = csv.writer(buf)
    starts = []
    for r in rows:
        starts.append(len(io.StringIO(buf.getvalue(), newline="").readlines()) + 1)
        w.writerow(r)
    return starts


@PROPERTY
@given(clips=st.lists(captions, min_size=1, max_size=6), data=st.data())
def test_audiocaps_roundtrip_property(tmp_path, clips, data):
    rows, aid = [], 0
    for k, caps in enumerate(clips):
        for c in caps:
            aid += 1
            rows.append([str(aid), f"yt{k}", str(10 * k), c])
    rows = data.draw(st.permutations(rows))  # a clip's rows need not be adjacent
    starts = _physical_line_starts([AC_HEADER] + rows)
    p = write_csv(tmp_path / "prop.csv", [AC_HEADER] + rows)
    got = read_audiocaps(p)
    first_row = {}  # clip id -> index of its first row in the file
    for i, r in enumerate(rows):
        first_row.setdefault(f"{r[1]}_{r[2]}", i)
    assert [c.id for c in got] == list(first_row)
    for c in got:
        mine = [r for r in rows if f"{r[1]}_{r[2]}" == c.id]
        assert c.captions == tuple(r[3].strip() for r in mine)  # file order
        assert c.meta["audiocap_ids"] == [r[0] for r in mine]
        assert c.origin == f"{p}:{starts[first_row[c.id] + 1]}"


@PROPERTY
@given(clips=st.lists(captions, min_size=1, max_size=6), data=st.data(),
       jsonl=st.booleans())
def test_plain_roundtrip_property(tmp_path, clips, data, jsonl):
    rows = [[f"d/{k}, x.wav", c] for k, caps in enumerate(clips) for c in caps]
    rows = data.draw(st.permutations(rows))
    if jsonl:
        p = write(tmp_path / "prop.jsonl", "".join(
            json.dumps({"path": r[0], "caption": r[1]}, ensure_ascii=False) + "\n"
            for r in rows))
    else:
        p = write_csv(tmp_path / "prop.csv", [["path", "caption"]] + rows)
    got = read_plain(p)
    order = list(dict.fromkeys(r[0] for r in rows))
    assert [c.id for c in got] == order
    for c in got:
        assert c.captions == tuple(r[1].strip() for r in rows if r[0] == c.id)
        assert c.audio == str(tmp_path / c.id)


def test_every_corpus_format_has_its_reader():
    from tsel_data.choices import CorpusFormat
    from tsel_data.corpus.manifests import READERS

    assert {str(f) for f in CorpusFormat} - {"auto"} == set(READERS)
