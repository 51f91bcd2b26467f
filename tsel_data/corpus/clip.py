"""The unit every manifest reader yields: one captioned audio clip."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field


@dataclass(frozen=True)
class Clip:
    """One captioned clip.

    id:       unique within a catalog (AudioCaps: ``{youtube_id}_{start_time}``).
    audio:    path of the audio file (as resolved by the reader).
    captions: every caption of the clip, in manifest order (at least one).
    offset:   seconds into the audio file where the clip begins (0 for pre-cut files).
    split:    the split the manifest assigns (``train``/``val``/``test``) or None.
    origin:   ``file:row`` of the first manifest row, for error messages.
    """

    id: str
    audio: str
    captions: tuple[str, ...]
    offset: float = 0.0
    split: str | None = None
    origin: str = ""
    meta: dict = field(default_factory=dict, compare=False, hash=False)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["captions"] = list(self.captions)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Clip":
        d = dict(d)
        d["captions"] = tuple(d["captions"])
        return cls(**d)
