"""What a path is before it is opened, names read from files kept inside their folder,
Unicode names matched in either normalisation (tsel_data/core/files.py): the three
checks every reader and every name goes through (docs/reliability.md section 10)."""
import os
import socket
import stat
import unicodedata

import pytest

from support.files import Fifo
from tsel_data.core.atomic import write_text
from tsel_data.core.files import check_input, inside, name_problem, path_problem, replace_problem, unicode_match
from tsel_data.errors import DatasetError, TselError


def _specials(tmp_path) -> dict:
    """Every kind of path that is no regular file to read, made here (a socket bound, a
    FIFO, a folder, links that loop or lead nowhere, a link to a character device)."""
    d = {"folder": tmp_path / "folder", "loop": tmp_path / "loop", "nowhere": tmp_path / "nowhere",
         "device": tmp_path / "device", "socket": tmp_path / "sock"}
    d["folder"].mkdir()
    os.symlink("loop", d["loop"])
    os.symlink("gone/x.csv", d["nowhere"])
    os.symlink(os.devnull, d["device"])
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(d["socket"]))
    sock.close()
    return d


def test_each_kind_of_path_is_named_without_opening_it(tmp_path):
    with Fifo(tmp_path / "fifo") as fifo:
        assert path_problem(fifo.path) == "is not a regular file: it is a FIFO (a named pipe)"
    assert not fifo.opened
    d = _specials(tmp_path)
    assert path_problem(d["folder"]) == "is a folder, not a file"
    assert path_problem(d["folder"], folder=True) is None
    assert path_problem(d["loop"]).startswith("is a symbolic link that loops")
    assert "which does not exist" in path_problem(d["nowhere"])
    assert path_problem(d["device"]) == "is not a regular file: it is a character device"
    assert path_problem(d["socket"]) == "is not a regular file: it is a socket"
    assert path_problem(tmp_path / "absent") == "does not exist"
    (tmp_path / "ok.csv").write_text("x")
    assert path_problem(tmp_path / "ok.csv") is None
    assert path_problem(tmp_path / "ok.csv", folder=True) == "is a file, not a folder"


def test_check_input_raises_the_callers_error_and_leaves_absence_to_it(tmp_path):
    d = _specials(tmp_path)
    with pytest.raises(DatasetError, match=r"device is not a regular file: it is a character device; fix it"):
        check_input(d["device"], DatasetError, "fix it")
    check_input(tmp_path / "absent", DatasetError)  # the caller's own message says what was looked for


@pytest.mark.parametrize("name,why", [
    ("../x", "climbs out"), ("a/../../x", "climbs out"), ("/etc/passwd", "absolute"), ("C:x", "absolute"),
    ("a\\b", "absolute"), ("", "empty"), ("a//b", "empty or '.'"), ("./a", "empty or '.'"), ("a\nb", "control"),
    (5, "not a file name"), (["a"], "not a file name"),
])
def test_a_name_that_would_leave_its_folder_is_refused(name, why, tmp_path):
    assert why in name_problem(name)
    with pytest.raises(ValueError):
        inside(str(tmp_path), name)


def test_a_name_inside_is_kept_but_not_through_a_link_that_leads_out(tmp_path):
    assert name_problem("train/x.tar") is None and name_problem("café/x.wav") is None
    assert inside(str(tmp_path), "train/x.tar") == os.path.join(str(tmp_path), "train/x.tar")
    os.symlink(str(tmp_path.parent), tmp_path / "out")
    with pytest.raises(ValueError, match="leads out of its folder"):
        inside(str(tmp_path), "out/victim.txt")


def test_names_match_in_either_unicode_normalisation(tmp_path):
    nfc, nfd = (unicodedata.normalize(f, "café") for f in ("NFC", "NFD"))
    assert nfc != nfd
    (tmp_path / nfd).mkdir()
    (tmp_path / nfd / f"{nfd}.wav").write_bytes(b"x")
    found = unicode_match(os.path.join(str(tmp_path), nfc, f"{nfc}.wav"))
    assert found is not None and os.path.isfile(found) and unicodedata.normalize("NFC", found).endswith(f"{nfc}.wav")
    assert unicode_match(os.path.join(str(tmp_path), "cafe.wav")) is None


def test_nothing_is_written_in_place_of_a_device_a_fifo_a_socket_or_a_folder(tmp_path):
    d = _specials(tmp_path)
    with Fifo(tmp_path / "fifo") as fifo:
        for path in (fifo.path, d["socket"], d["folder"]):
            assert "nothing is written in its place, not even with --force" in replace_problem(path)
            with pytest.raises(TselError, match="not even with --force"):
                write_text(str(path), "x")
    assert not fifo.opened and stat.S_ISFIFO(os.lstat(fifo.path).st_mode)
    assert replace_problem(d["device"]) is None  # a link: the link is replaced, never /dev/null behind it
    write_text(str(d["device"]), "x")
    assert os.path.isfile(d["device"]) and os.path.exists(os.devnull) and stat.S_ISCHR(os.stat(os.devnull).st_mode)
