"""The key tables of docs/config.md, generated from the schema.

docs/config.md holds one table per section between ``<!-- keys:SECTION -->`` and
``<!-- /keys -->`` markers. ``python -m tsel_data.config.doc docs/config.md`` rewrites
them; a test fails when the file and the schema differ.
"""
from __future__ import annotations

import json
import re
import sys
from dataclasses import fields

from ..core.doctables import rewrite
from .schema import SECTIONS, TOP_FIELDS, Config, SplitConfig

_BLOCK = re.compile(r"(<!-- keys:(?P<name>[\w.]+) -->\n)(?P<body>.*?)(<!-- /keys -->)", re.S)


def tables() -> dict[str, str]:
    """{section name: markdown table}; ``top`` for the top-level keys, ``splits`` for a split."""
    default = Config()
    out = {"top": _table([f for f in fields(Config) if f.name in TOP_FIELDS], default)}  # splits: see below
    out["splits"] = _table(fields(SplitConfig), SplitConfig())
    for sec, cls in SECTIONS.items():
        out[sec] = _table(fields(cls), cls())
    return out


def _table(specs, default) -> str:
    rows = ["| key | default | unit | meaning |", "|---|---|---|---|"]
    for f in specs:
        value = getattr(default, f.name)
        shown = json.dumps(value.to_json() if hasattr(value, "to_json") else list(value) if isinstance(value, tuple)
                           else value, ensure_ascii=False)
        m = f.metadata
        meaning = m["doc"]
        if m.get("choices"):
            meaning += "; one of " + ", ".join(f"`{c}`" for c in m["choices"])
        bounds = [f"{op} {m[k]:g}" if isinstance(m[k], float) else f"{op} {m[k]:,}"
                  for k, op in (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<")) if m.get(k) is not None]
        if bounds:
            meaning += f" ({', '.join(bounds)})"
        if m.get("integer"):
            meaning += "; whole numbers"
        rows.append(f"| `{f.name}` | `{shown}` | {m.get('unit') or '—'} | {meaning} |")
    return "\n".join(rows) + "\n"


def render(text: str) -> str:
    """``text`` with every marked table replaced by the schema's (KeyError on an unknown name)."""
    t = tables()
    return _BLOCK.sub(lambda m: m.group(1) + t[m.group("name")] + m.group(4), text)


def main(argv=None) -> None:
    rewrite((argv or sys.argv[1:] or ["docs/config.md"])[0], render)


if __name__ == "__main__":
    main()
