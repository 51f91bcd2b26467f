"""``tsel bank``: import measured RIR banks, build simulated ones, summarise any bank."""
from __future__ import annotations

import json

import click

from ..choices import RirMethod, values
from ..errors import BankError
from ..receivers import ALIASES, NAMES, RECEIVERS
from .options import Bounded, force_option

OWNER = "tsel bank"  # build and import: either may replace a bank the other wrote


def _floats(text: str, what: str) -> tuple:
    try:
        return tuple(float(v) for v in text.replace(",", " ").split())
    except ValueError:
        raise BankError(f"--{what}: expected numbers separated by commas, got {text!r}") from None


def _rooms(values) -> list | None:
    out = [r for v in values for r in v.replace(",", " ").split()]
    return out or None


BANK_RECEIVERS = [name for name, spec in RECEIVERS.items() if spec.bankable]

@click.group("bank")
def bank():
    """RIR banks: import TAU-SRIR DB / SOFA rooms, build simulated banks, show what a bank holds."""


@bank.group("import")
def import_group():
    """Convert a measured bank to the toolkit's HDF5 bank format."""


@import_group.command("tau")
@click.option("--src", required=True, type=click.Path(), help="The TAU-SRIR_DB directory (rirdata.mat, measinfo.mat, rirs_NN_<room>.mat).")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Bank file to write (.h5).")
@click.option("--rooms", multiple=True, help="Rooms to keep, by name or number (e.g. '1,2,tc352'); default all.")
@click.option("--format", "fmt", type=click.Choice(["foa", "mic"]), default="foa", show_default=True, help="Which TAU format to import (mic = tetrahedral).")
@force_option
def import_tau(src, out, rooms, fmt, force):
    """Import the TAU-SRIR DB as distributed (reads each trajectory once, never a whole file)."""
    from ..banks import open_bank  # as every command: its library module when it runs
    from ..store.outputs import claim_output

    with claim_output(out, force, OWNER), open_bank(src, kind="tau", format=fmt) as b:
        path = _write_with_bar(out, b, _rooms(rooms), {"importer": "tsel bank import tau"})
    click.echo(f"wrote {path}")


def _write_with_bar(out, b, rooms, provenance):
    """write_bank, into ``out`` as claimed, with a bar counting RIRs (a TAU room is
    thousands, read trajectory by trajectory); on a terminal only."""
    from ..banks.native import write_bank  # as every command: its library module when it runs
    from ..core.progress import bar

    names = [b.resolve_room(r) for r in rooms] if rooms else list(b.rooms)
    total = sum(len(t) for r in names for t in b.trajectories(r))
    with bar(total, "import", "RIR", None) as shown:
        return write_bank(out, b, rooms=rooms, provenance=provenance, overwrite=True,
                          progress=lambda room, t: (shown.set_postfix_str(f"{room} {t.id}", refresh=False),
                                                    shown.update(len(t))))


@import_group.command("sofa")
@click.argument("files", nargs=-1, required=True, type=click.Path())
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Bank file to write (.h5).")
@click.option("--format", "fmt", type=click.Choice([*NAMES, *ALIASES]), default=None, help="Array format, if the files do not say (SpatialScaper's _foa/_mic suffix does).")
@click.option("--rooms", multiple=True, help="Rooms to keep (default all).")
@click.option("--grouping", type=click.Choice(["auto", "rings", "runs"]), default="auto", show_default=True, help="How positions are grouped into trajectories (docs/banks.md).")
@force_option
def import_sofa(files, out, fmt, rooms, grouping, force):
    """Import SOFA SingleRoomSRIR files (one room each), e.g. SpatialScaper's <room>_foa.sofa."""
    from ..banks.sofa import SofaBank
    from ..store.outputs import claim_output

    with claim_output(out, force, OWNER), \
            SofaBank(list(files) if len(files) > 1 else files[0], format=fmt, grouping=grouping) as b:
        path = _write_with_bar(out, b, _rooms(rooms), {"importer": "tsel bank import sofa"})
    click.echo(f"wrote {path}")


@bank.command("info")
@click.argument("path", type=click.Path())
@click.option("--format", "fmt", default=None, help="For sources holding several formats (TAU: foa or mic).")
@click.option("--trajectories", "show_traj", is_flag=True, help="List every trajectory.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def info(path, fmt, show_traj, as_json):
    """Summarise a bank: rooms, format, RIR count, trajectories, azimuth/elevation coverage."""
    from ..banks import open_bank  # as every command: its library module when it runs

    with open_bank(path, format=fmt) as b:
        s = b.summary(trajectories=show_traj)
    if as_json:
        click.echo(json.dumps(s, indent=1))
        return
    click.echo(f"{s['source']}  ({s['kind']}, {s['format']} {'/'.join(s['channels'])}, {s['fs']} Hz, {s['rirs']} RIRs)")
    for r in s["rooms"]:
        num = f" #{r['number']}" if "number" in r else ""
        el, d = r["elevation_range_deg"], r["distance_range_m"]
        click.echo(
            f"  {r['room']}{num}: {r['rirs']} RIRs in {r['trajectories']} {'/'.join(r['kinds'])} trajectories; "
            f"azimuth coverage {r['azimuth_coverage_deg']:.0f} deg, elevation {el[0]}..{el[1]} deg, distance {d[0]}..{d[1]} m"
        )
        for t in r.get("trajectory_list", []):
            click.echo(f"    {t['id']}: {t['kind']}{' (closed)' if t['closed'] else ''}, {t['rirs']} RIRs, "
                       f"az {t['azimuth'][0]}..{t['azimuth'][1]}, el {t['elevation_mean']}, dist {t['distance_mean']} m")


@bank.command("build")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Bank file to write (.h5).")
@click.option("--format", "fmt", type=click.Choice(BANK_RECEIVERS), default="mic4", show_default=True,
              help="The receiver the bank's RIRs are simulated for.")
@click.option("--rooms", "n_rooms", type=Bounded("rooms", int), default=2, show_default=True, help="Number of simulated rooms.")
@click.option("--seed", type=Bounded("seed", int), default=0, show_default=True)
@click.option("--fs", type=Bounded("audio.fs", int), default=24000, show_default=True)
@click.option("--distances", default="1.0,1.5", show_default=True, help="Ring radii around the array (m).")
@click.option("--heights", default="-0.3,0,0.3", show_default=True, help="Ring heights relative to the array (m).")
@click.option("--step", "step_deg", type=Bounded("step"), default=5.0, show_default=True, help="Azimuth step along each ring (deg).")
@click.option("--rt60", default="0.3,0.8", show_default=True, help="RT60 range (s).")
@click.option("--side", type=Bounded("array.side"), default=0.11, show_default=True, help="mic4 square side (m).")
@click.option("--method", type=click.Choice(values(RirMethod)), default=None, help="RIR simulator (default hybrid).")
@click.option("--rir-seconds", type=Bounded("rir_seconds"), default=None, help="Cut RIRs to this length (default: full decay).")
@click.option("--demo", is_flag=True, help="The demo bank (4 rooms, 2 rings x 2 heights, 10 deg steps): the "
              "demo-moving preset's builtin:demo-bank.")
@force_option
def build(out, fmt, n_rooms, seed, fs, distances, heights, step_deg, rt60, side, method, rir_seconds, demo, force):
    """Simulate a bank in the TAU-SRIR DB's shape: circular trajectories around the array."""
    from ..banks.build import DEMO, build_bank
    from ..store.outputs import claim_output

    kw = dict(distances=_floats(distances, "distances"), heights=_floats(heights, "heights"), step_deg=step_deg,
              rt60=_floats(rt60, "rt60"), fs=fs, side=side, method=method, rir_seconds=rir_seconds)
    if len(kw["rt60"]) != 2:
        raise BankError("--rt60: give a range 'lo,hi' in seconds")
    if demo:
        ctx = click.get_current_context()
        flags = {"n_rooms": "--rooms", "distances": "--distances", "heights": "--heights", "step_deg": "--step",
                 "rt60": "--rt60"}
        given = [f for p, f in flags.items() if ctx.get_parameter_source(p) is not click.core.ParameterSource.DEFAULT]
        if given:
            raise BankError(f"--demo sets the rooms, distances, heights, step and RT60 itself; drop "
                            f"{', '.join(given)} or --demo")
        kw.update({k: v for k, v in DEMO.items() if k != "n_rooms"})
        n_rooms = DEMO["n_rooms"]
    from ..core.progress import bar  # tqdm: only for the commands that show a bar

    with claim_output(out, force, OWNER), bar(n_rooms, "simulate", "room", None) as shown:  # a bar on a terminal only
        path = build_bank(out, format=fmt, n_rooms=n_rooms, seed=seed, overwrite=True,
                          progress=lambda _room: shown.update(), **kw)
    click.echo(f"wrote {path}")
