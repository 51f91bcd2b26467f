"""One scene as a trainer sees it: what the reader returns (and the on-the-fly source)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.geometry import azimuth_difference, frame_centres
from .records import SceneRecord

@dataclass
class Scene:
    """One scene as a trainer sees it.

    audio:         float32 [C, T] (None when read with ``audio=False``).
    azimuth, elevation: float32 [S, F] degrees, array frame; NaN where a source has no
                   position (additive sources). distance: float32 [S, F] metres.
    active:        bool [S, F]. Source 0 is the target. S is this scene's own source
                   count (shard padding removed).
    mic_positions: float32 [C, 3] metres, array frame (FOA: zeros).
    record:        the scene's :class:`~tsel_data.store.records.SceneRecord` (room,
                   array pose, clips, captions, levels, seed), or None when read with
                   ``load_records=False``.
    query_type:    ``caption``, ``relational`` or ``composite``; query_relation: the
                   relation stated (None for a caption); pairing: ``random``, ``hard``,
                   ``easy``, ``same-kind`` or ``mixed`` (docs/queries.md). Datasets made
                   with default query settings read as ``caption`` / ``random``.
                   query_margin: the evidence of a relational query (NaN otherwise).
    receivers:     further receivers heard in the same pass (``scene.receivers``):
                   name -> (audio [C, T], mic_positions [C, 3]); None without them (the
                   reader opens them with ``receiver=NAME``).
    noise:         with ``[noise]``, kind -> (snr_db or None, level_dbfs); else None.
    channel_swap:  the channel-swap transform the scene went through (``tsel_data.augment``,
                   e.g. ``"az+90 -el"``), None as recorded.

    The renderer returns this type too (``render_scene``; the on-the-fly source hands it
    on as it is), and the shard writer stores it.
    """

    scene_id: str
    split: str
    index: int
    query: str
    audio: np.ndarray | None
    azimuth: np.ndarray
    elevation: np.ndarray
    distance: np.ndarray
    active: np.ndarray
    mic_positions: np.ndarray
    fs: int
    label_hop: float
    format: str
    record: SceneRecord | None = None
    query_type: str = "caption"
    query_relation: str | None = None
    pairing: str = "random"
    query_margin: float = float("nan")
    receivers: dict | None = None
    noise: dict | None = None
    channel_swap: str | None = None

    def __post_init__(self):
        # the query facts are the record's; kept flat for readers opened without records
        rec = self.record
        if rec is not None:
            self.query_type, self.query_relation, self.pairing = rec.query_type, rec.query_relation, rec.pairing
            self.query_margin = rec.query_margin

    @property
    def n_sources(self) -> int:
        return int(self.azimuth.shape[0])

    @property
    def n_frames(self) -> int:
        return int(self.azimuth.shape[1])

    @property
    def target_moving(self) -> bool:
        """Whether the target's azimuth changes over the scene (the record's flag if there
        is a record, else more than 0.5° of change in the labels)."""
        if self.record is not None and self.record.sources:
            return self.record.sources[0].moving
        az = self.azimuth[0]
        ok = np.isfinite(az)
        return bool(ok.any() and np.max(azimuth_difference(az[ok], az[ok][0])) > 0.5)

    def frame_times(self) -> np.ndarray:
        """Centre time (s) of each label frame, [F]."""
        return frame_centres(self.n_frames, self.label_hop)
