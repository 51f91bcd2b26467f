"""Options several commands share, and turning them into library arguments."""
from __future__ import annotations

import os

import click

from ..choices import Executor, MissingClipPolicy, values
from ..errors import TselError
from . import say


class Bounded(click.ParamType):
    """A number within the bounds the config schema declares for ``key`` (a config key,
    ``audio.fs``, or a command option of ``config.schema.CommandOptions``, ``tolerance``):
    ``nan``, ``inf``, ``-1`` or a fraction for a count are one line, never used. ``kind``:
    ``int`` or ``float``; ``parse``: text to number first (an export's ``500MB``)."""

    def __init__(self, key: str, kind: type = float, parse=None):
        self.key, self.kind, self.parse = key, kind, parse
        self.name = "integer" if kind is int else "number"

    def convert(self, value, param, ctx):
        from ..config.rules import option_problem  # the schema: loaded when an option is given

        if isinstance(value, str):
            try:
                value = self.parse(value) if self.parse else _number(value, self.kind)
            except TselError as e:
                self.fail(str(e), param, ctx)
            except ValueError:
                self.fail(f"{value!r} is not a number", param, ctx)
        problem = option_problem(self.key, value)
        if problem:
            self.fail(f"{problem}, got {value!r}", param, ctx)
        if self.kind is int:
            if float(value) != int(value):
                self.fail(f"{value!r} is not a whole number", param, ctx)
            return int(value)
        return value


def _number(text: str, kind: type):
    """``text`` as a number: a whole one exactly (a seed of 19 digits stays itself)."""
    if kind is int:
        try:
            return int(text.strip())
        except ValueError:
            pass
    return float(text)


def config_options(f):
    """--preset, --config, --corpus-dir, --split, --seed, --bank, --set."""
    opts = [
        click.option("--preset", help="A built-in preset (see `tsel presets`)."),
        click.option("--config", "config_path", type=click.Path(), help="A TOML config file."),
        click.option("--corpus-dir", type=click.Path(file_okay=False), help="Folder with the manifests and audio."),
        click.option("--split", "splits", multiple=True, metavar="NAME=COUNT", help="Scenes in a split (repeatable)."),
        click.option("--seed", type=Bounded("seed", int), help="Dataset seed."),
        click.option("--bank", type=click.Path(), help="RIR bank: a TAU-SRIR DB folder, SOFA file(s) or a tsel bank."),
        click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                     help="Override a config key, e.g. --set room.rt60='[\"uniform\", 0.3, 0.6]'."),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def manifest_option(f):
    """--manifest: one manifest for every split."""
    return click.option("--manifest", type=click.Path(dir_okay=False), help="One manifest for every split, its rows "
                        "shared out by their split column (e.g. your own path,caption,split CSV); its format is "
                        "detected; the corpus folder is its folder unless --corpus-dir says otherwise.")(f)


def allow_reuse_option(f):
    """--allow-reuse: past corpus.max_reuse."""
    return click.option("--allow-reuse", is_flag=True, help="Plan even when a split's count would use each clip in "
                        "more than corpus.max_reuse scenes.")(f)


def load(preset, config_path, corpus_dir, splits, seed, bank, overrides, validate=True, manifest=None):
    """The Config the config options describe (TselError for a malformed option)."""
    from ..config import load_config

    if not preset and not config_path:
        raise TselError("give --preset NAME or --config FILE.toml (see `tsel presets`)")
    if manifest:
        path = os.path.abspath(os.path.expanduser(manifest))
        corpus_dir = corpus_dir or os.path.dirname(path)
        inside = not os.path.relpath(path, os.path.abspath(os.path.expanduser(corpus_dir))).startswith("..")
        # relative to the corpus when it is in it: the plan then names no folder of this machine
        manifest = os.path.relpath(path, os.path.abspath(os.path.expanduser(corpus_dir))) if inside else path
    counts = {}
    for s in splits:
        name, _, count = s.partition("=")
        if not name or not count.isdigit():
            raise TselError(f"--split {s!r}: expected NAME=COUNT, e.g. --split train=100")
        counts[name] = int(count)
    return load_config(preset=preset, path=config_path, overrides=list(overrides), corpus_dir=corpus_dir,
                       seed=seed, splits=counts, bank=bank, validate=validate, manifest=manifest)


# `tsel generate` options that steer a run, not what it makes: `tsel check` takes them too, so
# a generate command line can be checked as it is (docs/commands/check.md)
RUN_ONLY = ("resume", "grow", "force", "quiet", "release", "missing", "min_scenes", "allow_reuse", "executor",
            "scheduler")


def run_only_options(f):
    """`tsel generate`'s run options, accepted and set aside (:data:`RUN_ONLY`)."""
    opts = [
        click.option("--resume", is_flag=True, help="Accepted as `tsel generate` takes it; steers a run only."),
        click.option("--grow", is_flag=True, help="Accepted as `tsel generate` takes it; steers a run only."),
        click.option("--force", is_flag=True, help="Accepted as `tsel generate` takes it; steers a run only."),
        click.option("--quiet", is_flag=True, help="No progress bars (they show only on a terminal anyway)."),
        click.option("--from", "release", type=click.Path(file_okay=False), hidden=True),
        click.option("--missing", type=click.Choice(values(MissingClipPolicy)), hidden=True),
        click.option("--min-scenes", hidden=True),
        click.option("--allow-reuse", is_flag=True, help="Accepted as `tsel generate` takes it; the check warns of "
                     "reuse either way."),
        click.option("--executor", type=click.Choice(values(Executor)), hidden=True),
        click.option("--scheduler", hidden=True),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def worker_count(n: int) -> int:
    """--workers: 0 means one per core."""
    return n if n else (os.cpu_count() or 1)


def executor_options(f):
    """--executor, --scheduler."""
    f = click.option("--scheduler", metavar="tcp://HOST:PORT", help="Dask scheduler address (--executor dask).")(f)
    f = click.option("--executor", type=click.Choice(values(Executor)), default="local",
                     show_default=True, help="Where shards render: a process pool, a Dask cluster, or a local "
                     "Dask cluster of --workers processes.")(f)
    return f


def note_unfinished(dataset_dir: str) -> None:
    """Say on stderr when a read-only tool looks at a dataset still being made (it then
    reads the shards finished so far)."""
    from ..store.reader import dataset_doc  # h5py: loaded by the commands that read datasets only

    note = dataset_doc(dataset_dir, unfinished=True).unfinished_note(dataset_dir)
    if note:
        click.echo(f"note: {say(note)}", err=True)


def roots_options(f):
    """--corpus-dir and --bank for commands over a planned dataset: where its inputs are
    now, when not where the plan says (the dataset or the corpus moved)."""
    f = click.option("--bank", type=click.Path(), help="Where the RIR bank is now (default: where the plan says).")(f)
    return click.option("--corpus-dir", type=click.Path(file_okay=False),
                        help="Where the corpus is now (default: where the plan says, relative to the dataset).")(f)


def force_option(f):
    """--force for commands that write files the user names (store/outputs.py)."""
    return click.option("--force", is_flag=True, help="Write even inside a dataset or bank folder, and over a file "
                        "this command did not write.")(f)
