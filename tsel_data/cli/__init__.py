"""The ``tsel`` command: a thin click layer over the library.

User mistakes (TselError) print one line and exit with 2, never a traceback. A command's
module is imported when the command is asked for, and imports its library module when it
runs, so ``tsel --version`` loads no command, ``tsel --help`` only the thin command
modules, and every command only what it uses (each process pays its imports again: pool
workers, job-array tasks, every call of a script; scipy.signal and pyroomacoustics take
seconds).
"""
from __future__ import annotations

import errno
import importlib
import os
import sys
from concurrent.futures.process import BrokenProcessPool

import click
from click.exceptions import NoArgsIsHelpError

from ..core.files import blocked_folder
from ..errors import TselError, WriteError, tidy_message
from ..runtime.signals import Stopped, stop_requested, stop_signals
from ..runtime.streams import guarded_output, output_note

# command name -> (module in this package, the click command in it)
COMMANDS = {
    "bank": ("bank", "bank"),
    "check": ("check", "check_cmd"),
    "corpus": ("corpus", "corpus"),
    "eval": ("eval", "eval_cmd"),
    "export": ("export", "export_cmd"),
    "finalize": ("dataset", "finalize_cmd"),
    "generate": ("dataset", "generate_cmd"),
    "inspect": ("inspect", "inspect_cmd"),
    "plan": ("dataset", "plan_cmd"),
    "presets": ("presets", "presets_cmd"),
    "render": ("dataset", "render_cmd"),
    "stats": ("stats", "stats_cmd"),
    "verify": ("verify", "verify_cmd"),
}


class _Commands(click.Group):
    """The commands of :data:`COMMANDS`, each imported when first asked for."""

    def list_commands(self, ctx):
        return sorted({*self.commands, *COMMANDS})

    def get_command(self, ctx, name):
        if name not in self.commands and name in COMMANDS:
            module, attr = COMMANDS[name]
            self.add_command(getattr(importlib.import_module(f"{__name__}.{module}"), attr), name)
        return self.commands.get(name)


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="tsel-data")
def cli():
    """Build datasets for text-queried target sound event localization."""


def main(argv=None) -> None:
    # every command stops the same way on SIGINT, SIGTERM and SIGHUP (runtime/signals.py);
    # a stdout or stderr that goes away (`| head`, a full log disk) never stops the work
    # nor reads as the dataset's failure (runtime/streams.py)
    with guarded_output() as (out, err):
        try:
            _main(argv)
        finally:
            output_note(out, err)


def _main(argv) -> None:
    with stop_signals():
        try:
            rc = _run(argv)
        except Stopped as e:
            _stopped(e, argv)
        except BrokenProcessPool:
            # a pool of the planning or clip-check stage lost a worker: to a stop signal
            # (the group's), or killed alone
            if stop_requested():
                _stopped(Stopped(stop_requested()), argv)
            _fail("a worker process died (killed, or out of memory?); nothing half-written was kept: run the command "
                  "again, with fewer --workers if memory is short")
    sys.exit(rc if isinstance(rc, int) else 0)


def _run(argv):
    try:
        return cli.main(args=argv, prog_name="tsel", standalone_mode=False)
    except WriteError as e:  # how to go on is the command's: only generate has --resume
        _fail(f"{e.problem}, then {_AFTER_WRITE.get(_command(argv), 'run it again') if e.resumable else 'run it again'}")
    except TselError as e:
        _fail(str(e))
    except NoArgsIsHelpError as e:  # `tsel` or `tsel bank` alone: the help is the answer
        click.echo(e.format_message())
        sys.exit(0)
    except click.UsageError as e:
        # click prints Usage / Try / Error on three lines; one line, with where to look
        ctx = e.ctx
        cmd = ctx.command_path if ctx is not None else "tsel"
        _fail(f"{e.format_message()} (see `{cmd} --help`)")
    except click.ClickException as e:
        _fail(e.format_message(), e.exit_code)
    except click.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except OSError as e:
        # full disk, unwritable output: say which file, no traceback
        blocked = e.filename and e.errno in (errno.ENOTDIR, errno.EEXIST) and blocked_folder(e.filename)
        if blocked:  # a folder to make where a file, a FIFO or a device is
            _fail(f"cannot make the folder {e.filename}: {blocked}; choose another path")
        _fail(f"{e.strerror or e}: {e.filename or ''}".rstrip(": "))


# what is kept after a stop, and how to go on, by command
_AFTER_STOP = {"generate": "rerun with --resume to continue: finished shards are kept",
               "render": "run it again to render the rest: finished shards are kept"}
# after a failed write of a shard (the others stay)
_AFTER_WRITE = {"generate": "rerun with --resume: finished shards are kept",
                "render": "run it again: finished shards are kept"}


def _command(argv) -> str:
    """The command asked for (``generate`` of ``tsel generate --out x``)."""
    args = sys.argv[1:] if argv is None else argv
    return next((a for a in args if not a.startswith("-")), "")


def _stopped(e: Stopped, argv) -> None:
    """The run was stopped by a signal: one line (unless the stop said so already while
    its tasks finished), and exit 128 + the signal's number."""
    after = _AFTER_STOP.get(_command(argv), "run it again: nothing half-written was kept")
    if e.now:
        what = f" {e.discarded} {e.noun}{'' if e.discarded == 1 else 's'} in flight discarded;" if e.discarded else ""
        line = f"stopped now ({e.signal_name}):{what} {after}"
    elif not e.announced:
        line = f"stopped ({e.signal_name}); {after}"
    else:
        line = ""
    try:
        if line:
            click.echo(line, err=True)
        sys.stdout.flush()
        sys.stderr.flush()
    except OSError:  # the terminal is gone
        pass
    if argv is None:
        # the command is the process: leave now, while the handlers still answer. Past
        # them the interpreter's own exit (joining threads, unloading modules) would die
        # of a further signal with no exit code of ours; everything of the run is closed
        os._exit(e.code)
    sys.exit(e.code)


def _fail(message: str, code: int = 2) -> None:
    """One line on stderr, whatever the message holds (names with newlines are escaped),
    naming files as the user would (no folder of the machine the user did not name)."""
    click.echo(f"error: {say(message)}", err=True)
    sys.exit(code)


def say(message: str) -> str:
    """A message as every ``error:``, ``warning:`` and ``note:`` line prints it: one line,
    its files named relative to the working folder (errors.tidy_message)."""
    return one_line(tidy_message(message))


def one_line(text: str) -> str:
    """``text`` with control characters escaped (\\n, \\t, \\x1b ...), so it prints as one line."""
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape").decode("ascii") for c in text)
