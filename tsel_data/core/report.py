"""What a check found: the report ``tsel check`` prints, for a config (job/preflight.py)
and for a written dataset (store/check.py).

Checks collect every problem instead of stopping at the first, so a user sees all of
them at once; ``report.raise_for_errors()`` turns the first into its TselError.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import TselError


@dataclass
class CheckReport:
    """What a check found.

    target: what was checked (config name or dataset folder). errors: problems that
    stop a run, as TselError instances (one-line messages). warnings: one-line strings
    for things that work but deserve a look. bad_clips: {"split", "clip_id", "origin",
    "problem"} for every clip the bad-clip policy applies to. facts: plain numbers
    (clips, scenes, shards, bytes) for the summary.
    """

    target: str
    errors: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    bad_clips: list = field(default_factory=list)
    facts: dict = field(default_factory=dict)
    _said: set = field(default_factory=set, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return not self.errors

    def error(self, e: TselError | str, cls=TselError) -> None:
        """Note a problem; the same line found twice (per split, per scene) is said once."""
        if str(e) not in self._said:
            self._said.add(str(e))
            self.errors.append(e if isinstance(e, TselError) else cls(e))

    def messages(self) -> list[str]:
        return [str(e) for e in self.errors]

    def raise_for_errors(self) -> None:
        """Raise the first problem (its own TselError subclass), noting how many more there are."""
        if not self.errors:
            return
        first = self.errors[0]
        if len(self.errors) == 1:
            raise first
        raise type(first)(f"{first} (and {len(self.errors) - 1} more problem(s); run `tsel check` to list them)")

    def to_dict(self) -> dict:
        return {"target": self.target, "ok": self.ok, "errors": self.messages(), "warnings": list(self.warnings),
                "bad_clips": list(self.bad_clips), "facts": self.facts}

    def summary_lines(self) -> list[str]:
        """Human summary (what was checked, counts); problems are in errors/warnings."""
        f = self.facts
        out = [f"{self.target}: {'OK' if self.ok else f'{len(self.errors)} problem(s)'}"]
        if f.get("receivers"):
            out.append("  heard by " + ", ".join(f"{r['name']} ({r['channels']} ch)" for r in f["receivers"]))
        for split, s in f.get("splits", {}).items():
            parts = []
            if "clips" in s:
                n, missing = s["clips"], s.get("missing", 0)
                share = f" ({n - missing:,} present, {100.0 * (n - missing) / n:.1f} %)" if missing and n else ""
                parts.append(f"{n:,} clips{share}")
            if s.get("bad"):
                parts.append(f"{s['bad']} bad ({s.get('policy', 'skip')})")
            if s.get("band_limited"):
                parts.append(band_limited_text(s["band_limited"], s.get("band_limited_rates", {}), f.get("fs")))
            if s.get("left_out"):
                parts.append(f"{s['left_out']:,} left out (below corpus.min_samplerate)")
            if "planned" in s:
                parts.append(f"{s['planned']} scenes planned")
            if "scenes" in s and "planned" not in s:
                parts.append(f"{s['scenes']} scenes")
            if "shards" in s:
                parts.append(f"{s['shards']} shards")
            out.append(f"  {split}: " + ", ".join(parts))
        if "estimated_bytes" in f:
            free = f.get("free_bytes")
            out.append(f"  output about {f['estimated_bytes'] / 1e9:.2f} GB"
                       + (f" ({free / 1e9:.1f} GB free)" if free is not None else ""))
        if "bytes" in f:
            out.append(f"  {f['bytes'] / 1e6:.1f} MB checked")
        return out


def band_limited_text(n: int, rates: dict, fs: int | None) -> str:
    """``7 band-limited (16 kHz: 7, empty above 8 of the scenes' 12 kHz; corpus.min_samplerate)``:
    clips recorded below the scenes' rate, which resampling cannot fill above their own Nyquist."""
    rates = {int(r): k for r, k in rates.items()}
    shown = ", ".join(f"{r / 1000:g} kHz: {k:,}" for r, k in sorted(rates.items()))
    reach = f" of the scenes' {fs / 2000:g} kHz" if fs else ""
    low = f", empty above {min(rates) / 2000:g}{reach}" if rates else ""
    return f"{n:,} band-limited ({shown}{low}; corpus.min_samplerate)"
