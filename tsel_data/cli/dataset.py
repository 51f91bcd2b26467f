"""``tsel generate | plan | render | finalize``."""
from __future__ import annotations

import click

from ..choices import MissingClipPolicy, values
from ..errors import TselError
from . import say
from .options import (Bounded, allow_reuse_option, config_options, executor_options, load, manifest_option,
                      roots_options, worker_count)


@click.command("generate")
@config_options
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--workers", type=Bounded("workers", int), default=0, help="Processes (default: number of cores).")
@click.option("--resume", is_flag=True, help="Continue an interrupted run in --out.")
@click.option("--grow", is_flag=True, help="Add scenes to the dataset in --out: give larger --split counts; the "
              "scenes it has stay byte-identical.")
@click.option("--force", is_flag=True, help="Write into a folder that holds other files (not a tsel-data dataset).")
@click.option("--quiet", is_flag=True, help="No progress bars.")
@click.option("--from", "release", type=click.Path(file_okay=False), help="Rebuild the recipe release REL (`tsel "
              "export recipes`) from --corpus-dir, reporting scene by scene (rebuild.json).")
@click.option("--missing", type=click.Choice(values(MissingClipPolicy)), default="skip", show_default=True,
              help="With --from: leave out scenes whose clip is missing, or substitute one (recorded).")
@click.option("--min-scenes", default="1", show_default=True, metavar="N|P%",
              help="With --from: the fewest scenes the rebuild must make, a count or a share of the release's "
                   "(e.g. 95%); fewer stops it before rendering (exit 2, no dataset).")
@manifest_option
@allow_reuse_option
@executor_options
def generate_cmd(preset, config_path, corpus_dir, splits, seed, bank, overrides, out_dir, workers, resume, grow, force,
                 quiet, release, missing, min_scenes, manifest, allow_reuse, executor, scheduler):
    """Plan, render and finalize a dataset in one go."""
    from ..job.pipeline import generate

    if release:
        return _rebuild(release, out_dir, corpus_dir, bank, missing, min_scenes, workers, quiet, force, executor,
                        scheduler, preset or config_path or splits or seed is not None or overrides or grow or manifest)
    cfg = load(preset, config_path, corpus_dir, splits, seed, bank, overrides, manifest=manifest)
    s = generate(cfg, out_dir, workers=worker_count(workers), resume=resume, progress=not quiet, executor=executor,
                 scheduler=scheduler, grow=grow, force=force, report=_report, allow_reuse=allow_reuse)
    total = sum(s["splits"].values())
    rate = sum(s["rendered_now"].values()) / s["render_seconds"] if s["render_seconds"] > 0 else 0.0
    click.echo(f"dataset {cfg.name} in {out_dir}: " + ", ".join(f"{k} {v:,}" for k, v in s["splits"].items())
               + f" scenes ({total:,} total)")
    click.echo(f"  plan {s['plan_seconds']:.1f} s, render {s['render_seconds']:.1f} s ({rate:.2f} scenes/s), "
               f"{s['bytes'] / 1e6:.1f} MB on disk" + ("" if cfg.recorded.on else f", {s['bad_clips']:,} bad clips skipped")
               + (" (see bad_clips.jsonl)" if s["bad_clips"] else "")
               + (f", {s['missing_clips']:,} clips missing (see missing_clips.json)" if s["missing_clips"] else ""))


def _rebuild(release, out_dir, corpus_dir, bank, missing, min_scenes, workers, quiet, force, executor, scheduler,
             planned) -> None:
    """``tsel generate --from REL``: the release's plan, rendered here, held against it."""
    from ..job.rebuild import rebuild

    if planned:
        raise TselError("--from takes its config and plan from the release: drop --preset, --config, --split, "
                        "--seed, --set, --manifest and --grow")
    rep = rebuild(release, out_dir, corpus_dir, bank, missing, workers=worker_count(workers), progress=not quiet,
                  force=force, executor=executor, scheduler=scheduler, min_scenes=min_scenes)
    if rep.get("note"):
        click.echo(say(rep["note"]))
    c = rep["clips"]
    moved = next(iter(rep["found"].items()), None)
    click.echo("clips: " + ", ".join(f"{v:,} {k}" for k, v in c.items())
               + (f" (e.g. {moved[0]} is {moved[1]} in the copy)" if moved else ""))
    for split, c in rep["splits"].items():
        click.echo(f"{split}: " + ", ".join(f"{v:,} {k}" for k, v in c.items()))
    for o in [o for o in rep["scenes"] if o["status"] != "identical"][:10]:
        click.echo(f"  {o['scene_id']}: {o['status']}" + (f" ({', '.join(o['parts'])})" if o["parts"] else "")
                   + (f": {o['why']}" if o["why"] else ""))
    click.echo(f"rebuilt {out_dir} from {release}; scene by scene: {out_dir}/rebuild.json")


def _report(line: str) -> None:
    """Notes from the corpus check (clips present per split, reuse), before any rendering:
    output, not errors, so stdout (stderr carries the progress bars and errors); one line
    each, naming files as error lines do."""
    click.echo(say(line))


@click.command("plan")
@config_options
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--workers", type=Bounded("workers", int), default=0, help="Processes for checking clips.")
@click.option("--grow", is_flag=True, help="Add scenes to the plan in --out (larger --split counts).")
@click.option("--force", is_flag=True, help="Write into a folder that holds other files (not a tsel-data dataset).")
@manifest_option
@allow_reuse_option
def plan_cmd(preset, config_path, corpus_dir, splits, seed, bank, overrides, out_dir, workers, grow, force, manifest,
             allow_reuse):
    """Check the corpus and write scene recipes only (plan/{split}.jsonl)."""
    from ..job.pipeline import estimate_bytes, plan_dataset
    from ..store.plans import shard_tasks

    cfg = load(preset, config_path, corpus_dir, splits, seed, bank, overrides, manifest=manifest)
    counts = plan_dataset(cfg, out_dir, workers=worker_count(workers), grow=grow, force=force, report=_report,
                          allow_reuse=allow_reuse)
    n_shards = len(shard_tasks(counts, cfg.output.shard_size))
    # the disk is checked by the commands that write audio: rendering may happen elsewhere
    click.echo("planned " + ", ".join(f"{k} {v:,}" for k, v in counts.items()) + f" scenes in {n_shards:,} shards "
               f"(0-{n_shards - 1}) in {out_dir}/plan; rendered, they take about "
               f"{estimate_bytes(cfg) / 1e9:.2f} GB")


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
@click.option("--workers", type=Bounded("workers", int), default=0, help="Processes (default: number of cores).")
@click.option("--quiet", is_flag=True)
@executor_options
@roots_options
def render_cmd(out_dir, shards, workers, quiet, executor, scheduler, corpus_dir, bank):
    """Render planned shards (skips complete ones), for job arrays."""
    from ..job.shards import render_shards  # not the pipeline: a render job does not import the sampler

    done = render_shards(out_dir, _parse_range(shards), workers=worker_count(workers), progress=not quiet,
                         executor=executor, scheduler=scheduler, corpus_dir=corpus_dir, bank=bank)
    click.echo("rendered " + ", ".join(f"{k} {v}" for k, v in done.items()) + " scenes")


@click.command("finalize")
@click.argument("out_dir", type=click.Path(file_okay=False))
@roots_options
def finalize_cmd(out_dir, corpus_dir, bank):
    """Check every shard against the plan and write dataset.json."""
    from ..job.shards import finalize

    doc = finalize(out_dir, corpus_dir, bank)
    click.echo("dataset.json written: " + ", ".join(f"{k} {v['scenes']}" for k, v in doc["splits"].items()))
