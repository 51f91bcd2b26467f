"""The receivers table of docs/format.md and docs/config.md, generated from the registry.

Each file holds it between ``<!-- receivers -->`` and ``<!-- /receivers -->``;
``python -m tsel_data.receivers.doc docs/format.md docs/config.md`` rewrites it, and a
test fails when a file and the registry differ.
"""
from __future__ import annotations

import re
import sys

from ..core.doctables import rewrite
from .registry import RECEIVERS

_BLOCK = re.compile(r"(<!-- receivers -->\n)(.*?)(<!-- /receivers -->)", re.S)


def table() -> str:
    rows = ["| `scene.format` | channels | how it hears | what it is | convention | source |", "|---|---|---|---|---|---|"]
    for spec in RECEIVERS.values():
        chans = "from `array.capsules`" if spec.configured else ", ".join(f"`{c}`" for c in spec.channel_names) \
            if len(spec.channel_names) <= 8 else f"{len(spec.channel_names)} (`{spec.channel_names[0]}` … " \
                                                  f"`{spec.channel_names[-1]}`)"
        if not chans:
            chans = f"{len(spec.layout(None))} (`mic0` …)"
        how = spec.model + (f" ({spec.baffle} baffle by default)" if spec.baffle else "") + (
            f" of `{spec.base}`" if spec.base else "")
        aka = f" (also `{'`, `'.join(spec.aliases)}`)" if spec.aliases else ""
        what = spec.summary + (f"; cannot tell: {spec.ambiguity}" if spec.ambiguity and spec.ambiguity != "lateral"
                               else "; hears only the angle from the median plane, φ and 180° − φ alike"
                               if spec.ambiguity == "lateral" else "")
        rows.append(f"| `{spec.name}`{aka} | {chans} | {how} | {what} | {spec.convention} | {spec.source or '—'} |")
    return "\n".join(rows) + "\n"


def render(text: str) -> str:
    return _BLOCK.sub(lambda m: m.group(1) + table() + m.group(3), text)


def main(argv=None) -> None:
    for path in argv or sys.argv[1:] or ["docs/format.md"]:
        rewrite(path, render)


if __name__ == "__main__":
    main()
