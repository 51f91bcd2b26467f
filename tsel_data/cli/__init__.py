"""The ``tsel`` command: a thin click layer over the library.

User mistakes (TselError) print one line and exit with 2, never a traceback. Each
command imports its library module when it runs, so ``tsel --help`` and every other
command start without loading what they do not use (scipy.signal and pyroomacoustics
take seconds to import).
"""
from __future__ import annotations

import sys

import click
from click.exceptions import NoArgsIsHelpError

from ..errors import TselError
from .bank import bank
from .check import check_cmd
from .corpus import corpus
from .eval import eval_cmd
from .export import export_cmd
from .inspect import inspect_cmd
from .stats import stats_cmd
from .verify import verify_cmd
from .dataset import finalize_cmd, generate_cmd, plan_cmd, render_cmd
from .presets import presets_cmd


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="tsel-data")
def cli():
    """Build datasets for text-queried target sound event localization."""


for _cmd in (generate_cmd, plan_cmd, render_cmd, finalize_cmd, check_cmd, inspect_cmd, stats_cmd, eval_cmd,
             export_cmd, verify_cmd, corpus, bank, presets_cmd):
    cli.add_command(_cmd)


def main(argv=None) -> None:
    try:
        rc = cli.main(args=argv, prog_name="tsel", standalone_mode=False)
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
        _fail(f"{e.strerror or e}: {e.filename or ''}".rstrip(": "))
    sys.exit(rc if isinstance(rc, int) else 0)


def _fail(message: str, code: int = 2) -> None:
    """One line on stderr, whatever the message holds (names with newlines are escaped)."""
    click.echo(f"error: {one_line(message)}", err=True)
    sys.exit(code)


def one_line(text: str) -> str:
    """``text`` with control characters escaped (\\n, \\t, \\x1b ...), so it prints as one line."""
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape").decode("ascii") for c in text)
