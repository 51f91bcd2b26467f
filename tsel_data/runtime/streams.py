"""stdout and stderr that may go away while a command runs.

``tsel generate ... | head`` closes the pipe after a line; a log on a full disk fails
every write; a terminal can be closed. None of that is the dataset's business: the work
goes on, and what the command prints after the failure is dropped. :func:`guarded_output`
wraps both streams for the length of a command: the first write that fails (EPIPE,
ENOSPC, EIO) is remembered, the stream's descriptor is pointed at ``/dev/null`` (so the
interpreter's own flush at exit finds nothing to fail on), and :func:`output_note` says
afterwards, on whichever stream still works, which stream failed and why, in words that
never read as the dataset's disk.
"""
from __future__ import annotations

import errno
import io
import os
import sys
from contextlib import contextmanager


class GuardedStream:
    """A text stream whose writes never raise OSError (see the module docstring);
    ``failed`` is the first error, or None."""

    def __init__(self, stream, name: str):
        self._stream, self.name, self.failed = stream, name, None

    def write(self, text):
        if self.failed is None:
            try:
                return self._stream.write(text)
            except OSError as e:
                self._fail(e)
        return len(text)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def flush(self):
        if self.failed is None:
            try:
                self._stream.flush()
            except OSError as e:
                self._fail(e)

    def _fail(self, e: OSError) -> None:
        self.failed = e
        try:  # what the text layer still holds goes to /dev/null, now and at exit
            null = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(null, self._stream.fileno())
            finally:
                os.close(null)
            self._stream.flush()
        except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
            pass  # no descriptor of its own (a test's capture): nothing to flush later

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _closed_at_start(stream, fd: int, name: str) -> GuardedStream:
    """A stream started closed (``tsel stats D >&-``: Python's sys.stdout is None): its
    descriptor is taken by /dev/null at once, so no file the command opens gets it (a
    shard opened as descriptor 1 would take whatever a library prints), and its writes
    are dropped; the note says it was closed."""
    try:
        os.fstat(fd)
    except OSError:
        null = os.open(os.devnull, os.O_WRONLY)
        if null != fd:
            os.dup2(null, fd)
            os.close(null)
    guarded = GuardedStream(stream if stream is not None else open(os.devnull, "w"), name)
    if stream is None:
        guarded.failed = OSError(errno.EBADF, "it was closed before the command started")
    return guarded


@contextmanager
def guarded_output():
    """``with guarded_output() as (out, err):`` sys.stdout and sys.stderr are
    :class:`GuardedStream` s for the block, the originals again after it."""
    before = sys.stdout, sys.stderr
    out, err = _closed_at_start(sys.stdout, 1, "stdout"), _closed_at_start(sys.stderr, 2, "stderr")
    sys.stdout, sys.stderr = out, err
    try:
        yield out, err
    finally:
        sys.stdout, sys.stderr = before


def output_note(out: GuardedStream, err: GuardedStream) -> None:
    """After a command: one line on stderr (or, when stderr failed and stdout did not,
    nowhere: stdout is the command's output) for each stream that failed."""
    for stream in (out, err):
        e = stream.failed
        if e is None:
            continue
        if e.errno == errno.EPIPE:
            why = f"{stream.name} was closed by the program reading it (a broken pipe, e.g. `| head`)"
        elif e.errno in (errno.ENOSPC, errno.EDQUOT):
            why = (f"{stream.name} could not be written: the disk that holds it (where the output was redirected, "
                   f"not the dataset's) is full")
        else:
            why = f"{stream.name} could not be written ({e.strerror or e})"
        err.write(f"note: {why}; the command ran to its end, and what it printed after that was dropped\n")
        err.flush()
