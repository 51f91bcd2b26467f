"""The tables of docs/spatial-language.md generated from the registries: every
vocabulary's bins (between ``<!-- vocabularies -->`` and ``<!-- /vocabularies -->``) and
the question types (``<!-- questions -->``). ``python -m tsel_data.scene.language_doc
docs/spatial-language.md`` rewrites them; a test fails when the page and the code differ.
"""
from __future__ import annotations

import re
import sys

from ..core.doctables import rewrite
from .questions import QUESTIONS
from .vocabularies import MOTION_WORDS, VOCABULARIES


def vocabularies() -> str:
    rows = ["| vocabulary | axis | word | when (array frame: az counter-clockwise from the front, +90° = left) |",
            "|---|---|---|---|"]
    for v in VOCABULARIES.values():
        axes = [("direction", ax) for ax in v.direction] + [(k, getattr(v, k)) for k in ("elevation", "distance")
                                                            if getattr(v, k) is not None]
        first = True
        for what, ax in axes:
            for word, when in ax.table:
                rows.append(f"| {'`' + v.name + '`' if first else ''} | {what} | {word} | {when} |")
                first = False
        rows += [f"| | room | {words} | {when} |" for words, when in v.room_table]
    rows.append(f"| every one | motion | {', '.join(MOTION_WORDS.values())} | the motion class approaching, "
                "receding, passing, circling (`scene/motion.py`) |")
    return "\n".join(rows) + "\n"


def questions() -> str:
    rows = ["| type | asks | decided on (margin) | needs |", "|---|---|---|---|"]
    for name, spec in QUESTIONS.items():
        asks, _, how = spec.summary.partition(": ")
        rows.append(f"| `{name}` | {asks} | {how} | {spec.needs or 'labels'} |")
    return "\n".join(rows) + "\n"


BLOCKS = {"vocabularies": vocabularies, "questions": questions}


def render(text: str) -> str:
    for name, make in BLOCKS.items():
        text = re.sub(rf"(<!-- {name} -->\n)(.*?)(<!-- /{name} -->)", lambda m: m.group(1) + make() + m.group(3),
                      text, flags=re.S)
    return text


def main(argv=None) -> None:
    for path in argv or sys.argv[1:] or ["docs/spatial-language.md"]:
        rewrite(path, render)


if __name__ == "__main__":
    main()
