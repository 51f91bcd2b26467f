"""``tsel generate | plan | render | finalize``."""
from __future__ import annotations

import os

import click

from ..errors import TselError


def _config_options(f):
    opts = [
        click.option("--preset", help="A built-in preset (see `tsel presets`)."),
        click.option("--config", "config_path", type=click.Path(dir_okay=False), help="A TOML config file."),
        click.option("--corpus-dir", type=click.Path(file_okay=False), help="Folder with the manifests and audio."),
        click.option("--split", "splits", multiple=True, metavar="NAME=COUNT", help="Scenes in a split (repeatable)."),
        click.option("--seed", type=int, help="Dataset seed."),
        click.option("--bank", type=click.Path(), help="RIR bank: a TAU-SRIR DB folder, SOFA file(s) or a tsel bank."),
        click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                     help="Override a config key, e.g. --set room.rt60='[\"uniform\", 0.3, 0.6]'."),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def _load(preset, config_path, corpus_dir, splits, seed, bank, overrides, validate=True):
    from ..config import load_config

    if not preset and not config_path:
        raise TselError("give --preset NAME or --config FILE.toml (see `tsel presets`)")
    counts = {}
    for s in splits:
        name, _, count = s.partition("=")
        if not name or not count.isdigit():
            raise TselError(f"--split {s!r}: expected NAME=COUNT, e.g. --split train=100")
        counts[name] = int(count)
    return load_config(preset=preset, path=config_path, overrides=list(overrides), corpus_dir=corpus_dir,
                       seed=seed, splits=counts, bank=bank, validate=validate)


def _workers(n):
    return n if n else (os.cpu_count() or 1)


def _executor_options(f):
    f = click.option("--scheduler", metavar="tcp://HOST:PORT", help="Dask scheduler address (--executor dask).")(f)
    f = click.option("--executor", type=click.Choice(["local", "dask", "dask-local"]), default="local",
                     show_default=True, help="Where shards render: a process pool, a Dask cluster, or a local "
                     "Dask cluster of --workers processes.")(f)
    return f


@click.command("generate")
@_config_options
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--workers", type=int, default=0, help="Processes (default: number of cores).")
@click.option("--resume", is_flag=True, help="Continue an interrupted run in --out.")
@click.option("--quiet", is_flag=True, help="No progress bars.")
@_executor_options
def generate_cmd(preset, config_path, corpus_dir, splits, seed, bank, overrides, out_dir, workers, resume, quiet,
                 executor, scheduler):
    """Plan, render and finalize a dataset in one go."""
    from ..generate import generate

    cfg = _load(preset, config_path, corpus_dir, splits, seed, bank, overrides)
    s = generate(cfg, out_dir, workers=_workers(workers), resume=resume, progress=not quiet, executor=executor,
                 scheduler=scheduler)
    total = sum(s["splits"].values())
    rate = sum(s["rendered_now"].values()) / s["render_seconds"] if s["render_seconds"] > 0 else 0.0
    click.echo(f"dataset {cfg.name} in {out_dir}: " + ", ".join(f"{k} {v}" for k, v in s["splits"].items())
               + f" scenes ({total} total)")
    click.echo(f"  plan {s['plan_seconds']:.1f} s, render {s['render_seconds']:.1f} s ({rate:.2f} scenes/s), "
               f"{s['bytes'] / 1e6:.1f} MB on disk, {s['bad_clips']} bad clips skipped"
               + (" (see bad_clips.jsonl)" if s["bad_clips"] else ""))


@click.command("plan")
@_config_options
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--workers", type=int, default=0, help="Processes for checking clips.")
def plan_cmd(preset, config_path, corpus_dir, splits, seed, bank, overrides, out_dir, workers):
    """Check the corpus and write scene recipes only (plan/{split}.jsonl)."""
    from ..generate import plan_dataset, shard_tasks, load_plan

    cfg = _load(preset, config_path, corpus_dir, splits, seed, bank, overrides)
    counts = plan_dataset(cfg, out_dir, workers=_workers(workers))
    n_shards = len(shard_tasks(*load_plan(out_dir)))
    click.echo("planned " + ", ".join(f"{k} {v}" for k, v in counts.items()) + f" scenes in {n_shards} shards "
               f"(0-{n_shards - 1}) in {out_dir}/plan")


def _parse_range(text: str | None):
    if not text:
        return None
    a, _, b = text.partition("-")
    if not a.isdigit() or (b and not b.isdigit()):
        raise TselError(f"--shards {text!r}: expected FIRST-LAST or N, e.g. --shards 0-99")
    lo, hi = int(a), int(b or a)
    if hi < lo:
        raise TselError(f"--shards {text!r}: last shard is before the first")
    return range(lo, hi + 1)


@click.command("render")
@click.argument("out_dir", type=click.Path(file_okay=False))
@click.option("--shards", help="A range of global shard numbers, e.g. 0-99 (default: all).")
@click.option("--workers", type=int, default=0, help="Processes (default: number of cores).")
@click.option("--quiet", is_flag=True)
@_executor_options
def render_cmd(out_dir, shards, workers, quiet, executor, scheduler):
    """Render planned shards (skips complete ones), for job arrays."""
    from ..generate import render_shards

    done = render_shards(out_dir, _parse_range(shards), workers=_workers(workers), progress=not quiet,
                         executor=executor, scheduler=scheduler)
    click.echo("rendered " + ", ".join(f"{k} {v}" for k, v in done.items()) + " scenes")


@click.command("finalize")
@click.argument("out_dir", type=click.Path(file_okay=False))
def finalize_cmd(out_dir):
    """Check every shard against the plan and write dataset.json."""
    from ..generate import finalize

    doc = finalize(out_dir)
    click.echo("dataset.json written: " + ", ".join(f"{k} {v['scenes']}" for k, v in doc["splits"].items()))
