"""The ``tsel`` command as tests run it: in this process through the real entry point
(quick, and what a user sees), or in a fresh interpreter when the test needs one (signals,
imports, a process of its own)."""
from __future__ import annotations

import contextlib
import io
import subprocess
import sys
import traceback

import pytest


def cli(capsys, *argv) -> tuple[int, str, str]:
    """``tsel ARGV`` in this process: (exit code, stdout, stderr)."""
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as ex:
        main([str(a) for a in argv])
    out = capsys.readouterr()
    return ex.value.code, out.out, out.err


def error_line(code: int, err: str, *needles) -> str:
    """The one ``error:`` line of a command that must fail with exit 2 (no traceback),
    holding every one of ``needles``."""
    lines = [x for x in err.splitlines() if x.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, (code, err)
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


class InProcessCli:
    """``tsel ARGS`` through the real entry point (tsel_data.cli:main), in this process,
    its output captured (the ``tsel_cli`` fixture)."""

    def __init__(self, capsys):
        self.capsys = capsys

    def run(self, *argv) -> tuple[int, str, str]:
        return cli(self.capsys, *argv)

    def ok(self, *argv) -> str:
        code, out, err = self.run(*argv)
        assert code == 0, err
        return out

    def refused(self, *argv) -> str:
        return error_line(*self.run(*argv)[::2])


def completed(*argv) -> subprocess.CompletedProcess:
    """``tsel ARGV`` in this process, as a finished subprocess would report it: exit code,
    stdout, stderr; an exception that escapes the command is exit 1 with its traceback on
    stderr, as the interpreter would print it."""
    from tsel_data.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in argv])
            code = 0
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except Exception:  # noqa: BLE001 (what a user would see)
            traceback.print_exc()
            code = 1
    return subprocess.CompletedProcess(list(argv), code, out.getvalue(), err.getvalue())


def tsel(*args, **kw) -> subprocess.CompletedProcess:
    """``tsel ARGS`` in a fresh interpreter, its output captured as text."""
    return subprocess.run([sys.executable, "-m", "tsel_data.cli", *map(str, args)], capture_output=True, text=True,
                          **kw)


def one_line_error(r: subprocess.CompletedProcess, *needles) -> str:
    """The one ``error:`` line of a finished subprocess that had to fail with exit 2."""
    return error_line(r.returncode, r.stderr, *needles)
