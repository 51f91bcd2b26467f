"""The dataset card alone (``tsel export card``): README.md and the statistics figure of
any finished dataset, for a folder that publishes it some other way."""
from __future__ import annotations

from .base import SplitResult, Writer, WriterOption
from .card import FIGURE_FILE


class CardWriter(Writer):
    name = "card"
    summary = "The dataset card: README.md with the Hub's YAML header, and the statistics figure."
    COMMON = (WriterOption("card", "Write the dataset card (README.md).", True, flag=True),
              WriterOption("figure", f"Draw the statistics figure ({FIGURE_FILE}).", True, flag=True))

    def write_split(self, job, split: str) -> SplitResult:
        return SplitResult([], {"scenes": job.doc.counts[split]})

    def lines(self, result) -> list:
        return [f"card: {result.out}/README.md" + (f", figure: {result.out}/{FIGURE_FILE}"
                                                    if FIGURE_FILE in result.shared else "")]
