"""Recorded SELD datasets as distributed (corpus/seld.py): the layout found, label CSVs of
five and six columns read row by row, every bad row one line naming the file and the row,
sources of a window told apart by class, actor and direction, ontologies from a file."""
from __future__ import annotations

import json
import math
import os
import shutil

import numpy as np
import pytest

from tsel_data.choices import RecordedSet
from tsel_data.corpus.ontologies import STARSS, read_ontology
from tsel_data.corpus.seld import SETS, find_recordings, read_labels, window_sources
from tsel_data.errors import ConfigError

STARSS23 = SETS[RecordedSet.STARSS23]


def _csv(tmp_path, text: str, name: str = "fold3_room1_mix001.csv") -> str:
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_five_and_six_column_rows_are_read_with_distances_in_metres(tmp_path):
    six = read_labels(_csv(tmp_path, "0,1,2,30,-10,150\n1,1,2,31,-10,152\n"), STARSS23, STARSS)
    assert six.frame.tolist() == [0, 1] and six.cls.tolist() == [1, 1] and six.source.tolist() == [2, 2]
    assert six.azimuth.tolist() == [30.0, 31.0] and six.elevation.tolist() == [-10.0, -10.0]
    assert six.distance.tolist() == pytest.approx([1.5, 1.52]) and six.has_distance
    five = read_labels(_csv(tmp_path, "4,0,0,-170,5\n", "b.csv"), STARSS23, STARSS)
    assert five.frame.tolist() == [4] and math.isnan(five.distance[0]) and not five.has_distance


def test_an_azimuth_of_180_is_our_minus_180(tmp_path):
    lab = read_labels(_csv(tmp_path, "0,3,0,180,0\n1,3,0,-180,0\n"), STARSS23, STARSS)
    assert lab.azimuth.tolist() == [-180.0, -180.0]


@pytest.mark.parametrize("row,needles", [
    ("0,1,2,30", ["a row of 4 fields", "5 or 6 whole numbers"]),
    ("0,1,2,30,-10,150,7", ["a row of 7 fields"]),
    ("0,1,2,thirty,-10", ["azimuth 'thirty' is not a whole number"]),
    ("0,1,2,30.5,-10", ["azimuth '30.5' is not a whole number"]),
    ("0,13,0,30,-10", ["class 13 is not in the ontology", "recorded.ontology"]),
    ("0,1,0,181,0", ["azimuth 181 is outside [-180, 180]"]),
    ("0,1,0,10,91", ["elevation 91 is outside [-90, 90]"]),
    ("-1,1,0,10,0", ["frame -1 is negative"]),
    ("0,1,0,10,0,-5", ["distance -5 is negative"]),
])
def test_a_bad_row_is_one_line_naming_the_file_and_the_row(tmp_path, row, needles):
    path = _csv(tmp_path, f"0,1,2,30,-10\n{row}\n")
    with pytest.raises(ConfigError) as e:
        read_labels(path, STARSS23, STARSS)
    msg = str(e.value)
    assert msg.startswith(f"{path}:2: ") and "\n" not in msg, msg
    for n in needles:
        assert n in msg, msg


def test_each_set_reads_its_own_columns(tmp_path):
    nigens = SETS[RecordedSet.TAU_NIGENS_2020]
    lab = read_labels(_csv(tmp_path, "3,13,1,20,10\n"), nigens, nigens.ontology)  # piano, track 1
    assert lab.cls.tolist() == [13] and lab.source.tolist() == [1]
    with pytest.raises(ConfigError, match="class 12 is not in the ontology"):
        read_labels(_csv(tmp_path, "3,12,1,20,10\n", "c.csv"), SETS[RecordedSet.TAU_NIGENS_2021],
                    SETS[RecordedSet.TAU_NIGENS_2021].ontology)
    stereo = SETS[RecordedSet.DCASE2025_STEREO]
    lab = read_labels(_csv(tmp_path, "0,4,0,-45,230,1\n", "d.csv"), stereo, stereo.ontology)
    assert lab.azimuth.tolist() == [-45.0] and math.isnan(lab.elevation[0]) and lab.distance[0] == pytest.approx(2.3)
    # columns of your own (recorded.columns)
    lab = read_labels(_csv(tmp_path, "7,30,-5,2,0\n", "e.csv"), STARSS23, STARSS,
                      ("frame", "azimuth", "elevation", "class", "source"))
    assert (lab.frame[0], lab.azimuth[0], lab.elevation[0], lab.cls[0]) == (7, 30.0, -5.0, 2)


def test_a_source_without_a_direction_leaves_both_angles_empty(tmp_path):
    lab = read_labels(_csv(tmp_path, "0,8,0,,\n"), STARSS23, STARSS)
    assert math.isnan(lab.azimuth[0]) and math.isnan(lab.elevation[0])
    with pytest.raises(ConfigError, match="elevation '' is not a whole number"):
        read_labels(_csv(tmp_path, "0,8,0,20,\n", "b.csv"), STARSS23, STARSS)


def test_sources_of_a_window_are_class_and_actor_and_two_at_once_stay_apart(tmp_path):
    rows = []
    for f in range(20):
        rows += [f"{f},1,1,30,0", f"{f},4,1,30,0"] if f < 10 else []  # one actor speaks and laughs: two sources
        rows += [f"{f},8,0,{120 - f},0", f"{f},8,0,{-150 + f},10"]  # two music sources, source 0 both, crossing no path
    lab = read_labels(_csv(tmp_path, "\n".join(rows) + "\n"), STARSS23, STARSS)
    srcs = window_sources(lab, 0, 20)
    assert [s.key for s in srcs] == [(1, 1, 0), (4, 1, 0), (8, 0, 0), (8, 0, 1)]
    music = [s for s in srcs if s.cls == 8]
    # each track keeps to its own direction, frame after frame
    starts = sorted(float(m.azimuth[0]) for m in music)
    assert starts == [-150.0, 120.0]
    for m in music:
        assert np.all(np.abs(np.diff(m.azimuth)) <= 1.0) and m.active.all()
    speech = srcs[0]
    assert speech.active[:10].all() and not speech.active[10:].any() and np.isnan(speech.azimuth[10:]).all()
    # a window elsewhere sees only what its frames hold, on its own frame grid
    later = window_sources(lab, 10, 10)
    assert [s.key for s in later] == [(8, 0, 0), (8, 0, 1)] and later[0].azimuth.shape == (10,)


def test_the_layout_is_found_as_distributed(demo_recordings):
    foa = find_recordings(demo_recordings, "foa")
    assert [r.audio for r in foa] == ["foa_dev/dev-test-sony/fold4_room3_mix003.wav",
                                      "foa_dev/dev-test-sony/fold4_room4_mix004.wav",
                                      "foa_dev/dev-train-sony/fold3_room1_mix001.wav",
                                      "foa_dev/dev-train-sony/fold3_room2_mix002.wav"]
    assert foa[0].metadata == "metadata_dev/dev-test-sony/fold4_room3_mix003.csv"
    assert (foa[0].fold, foa[0].room, foa[2].fold, foa[2].room) == (4, 3, 3, 1)
    assert [r.audio.replace("mic_dev", "foa_dev") for r in find_recordings(demo_recordings, "mic")] == \
        [r.audio for r in foa]


def test_layout_problems_are_one_line(tmp_path, demo_recordings):
    root = tmp_path / "starss"
    shutil.copytree(demo_recordings, root)
    os.remove(root / "metadata_dev" / "dev-test-sony" / "fold4_room4_mix004.csv")
    with pytest.raises(ConfigError, match=r"fold4_room4_mix004.wav has no label file \(expected .*fold4_room4_mix004"
                                          r".csv\); add it or remove the recording"):
        find_recordings(str(root), "foa")
    with pytest.raises(ConfigError, match="has no stereo_dev/ but has foa_dev/, mic_dev/: set scene.format"):
        find_recordings(str(root), "stereo")
    evaluation = tmp_path / "eval"
    shutil.copytree(root / "foa_dev", evaluation / "foa_eval")
    with pytest.raises(ConfigError, match="has no labels .metadata_eval/ is missing.: an evaluation set without "
                                          "labels cannot be a test set"):
        find_recordings(str(evaluation), "foa")
    with pytest.raises(ConfigError, match="recorded dataset folder .* not found"):
        find_recordings(str(tmp_path / "nowhere"), "foa")


def test_your_own_recordings_need_only_a_csv_beside_each_wav(tmp_path, demo_recordings):
    own = tmp_path / "own"
    own.mkdir()
    shutil.copy(os.path.join(demo_recordings, "foa_dev", "dev-test-sony", "fold4_room3_mix003.wav"), own / "kitchen.wav")
    shutil.copy(os.path.join(demo_recordings, "metadata_dev", "dev-test-sony", "fold4_room3_mix003.csv"),
                own / "kitchen.csv")
    (r,) = find_recordings(str(own), "foa")
    assert (r.audio, r.metadata, r.fold, r.room) == ("kitchen.wav", "kitchen.csv", None, None)


def test_an_ontology_file_names_classes_and_their_captions(tmp_path):
    csv_file = tmp_path / "classes.csv"
    csv_file.write_text("index,name,captions\n0,kettle,A kettle whistles|Water boils in a kettle\n3,cat,A cat meows\n")
    onto = read_ontology(str(csv_file))
    assert sorted(onto) == [0, 3] and onto[0].name == "kettle"
    assert onto[0].captions == ("A kettle whistles", "Water boils in a kettle")
    js = tmp_path / "classes.json"
    js.write_text(json.dumps({"2": {"name": "drill", "captions": ["A drill whirs"]}}))
    assert read_ontology(str(js))[2].captions == ("A drill whirs",)
    for text, needle in (("idx,name\n", "the first row must be the header index,name,captions"),
                         ("index,name,captions\nx,cat,A cat meows\n", "class index 'x' is not a whole number"),
                         ("index,name,captions\n1,cat,\n", "needs an index >= 0, a name and at least one caption"),
                         ("index,name,captions\n1,cat,meow\n1,dog,bark\n", "class index 1 is given twice"),
                         ("index,name,captions\n0,woman,A person speaks\n1,man,A Person speaks\n",
                          "the caption 'A Person speaks' is given to classes 0 and 1; a query must name one class")):
        csv_file.write_text(text)
        with pytest.raises(ConfigError, match=needle):
            read_ontology(str(csv_file))
    with pytest.raises(ConfigError, match="is a folder; give a CSV"):
        read_ontology(str(tmp_path))


def test_every_built_in_class_has_several_wordings_and_no_wording_serves_two_classes():
    for s in SETS.values():
        words = [c for k in s.ontology.values() for c in k.captions]
        assert all(len(k.captions) >= 3 for k in s.ontology.values()), s.name
        assert len(words) == len(set(words)), s.name
    assert len(SETS[RecordedSet.STARSS23].ontology) == 13 and len(SETS[RecordedSet.TAU_NIGENS_2020].ontology) == 14
    assert len(SETS[RecordedSet.TAU_NIGENS_2021].ontology) == 12


def test_copies_as_people_make_them_are_read(tmp_path, demo_recordings):
    """A macOS copy's ``._NAME.wav``, a FIFO, a label file saved with a byte-order mark and
    CRLF line ends, a linked folder: what a copy of STARSS23 can hold besides the data."""
    root = tmp_path / "starss"
    shutil.copytree(demo_recordings, root)
    test = root / "foa_dev" / "dev-test-sony"
    (test / "._fold4_room3_mix003.wav").write_bytes(b"\0\5\x16\7")
    os.mkfifo(test / "fold9_room9_mix999.wav")
    meta = root / "metadata_dev" / "dev-test-sony" / "fold4_room3_mix003.csv"
    meta.write_bytes(b"\xef\xbb\xbf" + meta.read_bytes().replace(b"\n", b"\r\n"))
    linked = tmp_path / "elsewhere"
    shutil.move(str(root / "foa_dev" / "dev-train-sony"), linked)
    os.symlink(linked, root / "foa_dev" / "dev-train-sony")
    recs = find_recordings(str(root), "foa")
    assert [r.audio.split("/")[-1] for r in recs] == ["fold4_room3_mix003.wav", "fold4_room4_mix004.wav",
                                                     "fold3_room1_mix001.wav", "fold3_room2_mix002.wav"]
    lab = read_labels(str(meta), STARSS23, STARSS)
    assert lab.frame[0] == 0 and len(lab.frame) > 100


def test_a_source_appearing_far_from_the_others_is_a_source_of_its_own(tmp_path):
    """Two music sources, both source 0: A at 120 deg from frame 0, B at -60 deg from frame
    20 (while A plays); A stops at 50, B goes on. Each keeps its own track."""
    rows = [f"{f},8,0,120,0" for f in range(50)] + [f"{f},8,0,-60,0" for f in range(20, 80)]
    srcs = window_sources(read_labels(_csv(tmp_path, "\n".join(rows) + "\n"), STARSS23, STARSS), 0, 100)
    tracks = {(float(np.nanmin(s.azimuth)), float(np.nanmax(s.azimuth))): np.flatnonzero(s.active) for s in srcs}
    assert set(tracks) == {(120.0, 120.0), (-60.0, -60.0)}
    assert tracks[120.0, 120.0].tolist() == list(range(50)) and tracks[-60.0, -60.0].tolist() == list(range(20, 80))


def test_a_row_given_twice_is_one_annotation(tmp_path):
    text = "0,1,1,30,0\n1,1,1,30,0\n"
    lab = read_labels(_csv(tmp_path, text + text), STARSS23, STARSS)
    assert lab.frame.tolist() == [0, 1]
    assert len(window_sources(lab, 0, 10)) == 1


def test_a_number_beyond_any_label_file_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r":1: frame 99999999999999999999999 is out of range"):
        read_labels(_csv(tmp_path, "99999999999999999999999,5,0,10,10\n"), STARSS23, STARSS)


def test_a_label_file_without_its_recording_and_folders_one_level_off(tmp_path, demo_recordings):
    root = tmp_path / "starss"
    shutil.copytree(demo_recordings, root)
    os.remove(root / "foa_dev" / "dev-test-sony" / "fold4_room3_mix003.wav")
    with pytest.raises(ConfigError, match=r"fold4_room3_mix003.csv has no recording .* a download cut short"):
        find_recordings(str(root), "foa")
    with pytest.raises(ConfigError, match="is a folder inside a DCASE-layout dataset: give the folder that holds "
                                          "foa_dev/"):
        find_recordings(str(root / "foa_dev"), "foa")
    with pytest.raises(ConfigError, match="holds no foa_dev/ itself; .*starss holds it: give that folder"):
        find_recordings(str(tmp_path), "foa")
    # labels of another edition beside the audio: named
    os.rename(root / "metadata_dev", root / "metadata_dev_2024")
    with pytest.raises(ConfigError, match=r"has no labels .metadata_dev/ is missing.: .*metadata_dev_2024/: rename"):
        find_recordings(str(root), "foa")


def test_upper_case_names_and_a_link_back_up_are_read_once(tmp_path, demo_recordings):
    root = tmp_path / "starss"
    shutil.copytree(demo_recordings, root)
    meta = root / "metadata_dev" / "dev-test-sony"
    os.rename(meta / "fold4_room3_mix003.csv", meta / "FOLD4_ROOM3_MIX003.CSV")
    os.symlink("..", root / "foa_dev" / "dev-test-sony" / "loop")
    os.symlink("..", meta / "loop")
    recs = find_recordings(str(root), "foa")
    assert len(recs) == 4 and recs[0].metadata.endswith("FOLD4_ROOM3_MIX003.CSV")
