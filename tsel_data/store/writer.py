"""Write one shard: ``{split}/shard-NNNNN.h5`` and its ``.json`` twin.

Both files are written under temporary names and renamed only when complete, JSON
first and HDF5 last, so a shard whose ``.h5`` exists under its final name is whole.
HDF5 bytes are deterministic (``track_times=False``, fixed chunking, no timestamps), so
a resumed or re-run job writes identical files.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
from dataclasses import replace

import h5py
import numpy as np

from ..choices import AudioCoding
from ..core.atomic import _fsync_dir, atomic_write, remove_stale_tmp, start_writeback, write_error
from ..core.jsonable import jsonable
from ..receivers import receiver
from .codings import create_audio, encode
from .dataset import FORMAT_VERSION, ShardEntry
from .integrity import FileSeal, Seal
from .layout import Layout, shard_names
from .layout import DESCRIPTORS_GROUP, HARDWARE_GROUP, NOISE_GROUP, RECEIVERS_GROUP
from .records import LABEL_KEYS
from .sanity import check_scene
from .scene import Scene

# Space a write needs beyond its bytes (HDF5 metadata, the file system), as a fraction:
# the free-space check before each write leaves this margin (see _check_space).
SPACE_MARGIN = 0.25


# Per-scene query columns of a shard with extended queries (docs/format.md): name -> default.
QUERY_COLUMNS = {"query_type": "caption", "query_relation": "", "query_margin": float("nan"), "pairing": "random"}
# per source [N, S] (NaN where unmeasured or padded), from the records (output.descriptors)
DESCRIPTOR_KEYS = ("drr_db", "c50_db", "edt_s", "t30_s")


def _query_row(s: Scene) -> dict | None:
    """A scene's values of the shard's query columns (:data:`QUERY_COLUMNS`), or None for
    a scene of default queries."""
    rec = s.record
    if rec is None or not rec.extended:
        return None
    return {"query_type": rec.query_type, "query_relation": rec.query_relation or "", "query_margin": rec.query_margin,
            "pairing": rec.pairing}


# Per-scene columns of a shard of a dataset with [hardware] (docs/format.md "Microphones as built"),
# per receiver: name -> (dtype, fill where a scene has none). Per capsule [N, C] but
# sensitivity_dbfs and highpass_order [N]; a capsule's clock is its device's.
HARDWARE_COLUMNS = {"gain_db": np.float32, "delay_us": np.float32, "highpass_hz": np.float32,
                    "tilt_db": np.float32, "self_noise_dba": np.float32, "self_noise_dbfs": np.float32,
                    "device": np.int16, "clock_offset_us": np.float32, "clock_ppm": np.float32,
                    "sensitivity_dbfs": np.float32, "highpass_order": np.int16}


def _hardware_rows(rec) -> list[dict | None]:
    """Each receiver's values of :data:`HARDWARE_COLUMNS` (the record's ``array`` first,
    then its ``receivers``), None where a receiver has no hardware."""
    if rec is None:
        return []
    out = []
    for a in (rec.array, *rec.receivers):
        hw = a.hardware
        if hw is None:
            out.append(None)
            continue
        nan = [float("nan")] * hw.n_channels
        offset, ppm = hw.channel_clocks()
        out.append({"gain_db": hw.gain_db, "delay_us": hw.delay_us, "highpass_hz": hw.highpass_hz,
                    "tilt_db": hw.tilt_db, "self_noise_dba": hw.self_noise_dba or nan,
                    "self_noise_dbfs": hw.self_noise_dbfs or nan, "device": hw.devices or [0] * hw.n_channels,
                    "clock_offset_us": offset, "clock_ppm": ppm, "sensitivity_dbfs": hw.sensitivity_dbfs,
                    "highpass_order": hw.highpass_order})
    return out


def _descriptor_row(s: Scene) -> dict | None:
    """A scene's descriptors as the shard's ``descriptors/`` datasets hold them, or None
    for a scene without (``output.descriptors`` off)."""
    rec = s.record
    if rec is None:
        return None
    if all(src.motion is None and src.acoustics is None for src in rec.sources) and rec.room.volume_m3 is None:
        return None
    acoustics = [src.acoustics or {} for src in rec.sources]
    return {"sources": {key: [a.get(key) for a in acoustics] for key in DESCRIPTOR_KEYS},
            "bands": [a.get("t30_bands_s") or {} for a in acoustics], "motion": [src.motion or "" for src in rec.sources],
            "volume_m3": rec.room.volume_m3, "floor_area_m2": rec.room.floor_area_m2}


def _nan(v) -> float:
    return np.nan if v is None else float(v)


def write_shard(out_dir: str, split: str, shard: int, scenes: list[Scene], attrs: dict,
                fingerprint: str = "") -> ShardEntry:
    """Write a shard of scenes already in memory (see :class:`ShardWriter`, which streams)."""
    with ShardWriter(out_dir, split, shard, len(scenes), attrs, fingerprint) as w:
        for s in scenes:
            w.add(s)
    return w.entry


class ShardWriter:
    """Write one shard scene by scene, atomically, and seal it.

    ``with ShardWriter(out_dir, split, shard, n_scenes, attrs, fingerprint) as w:
    w.add(scene)`` n times; ``w.entry`` is then the shard's entry for ``dataset.json``.
    Audio goes to the shard's HDF5 file as each scene arrives, so memory holds one
    scene's audio, not the shard's (labels and records, small, are kept until the end).

    attrs: :func:`~tsel_data.store.dataset.shard_attrs` (``audio_coding`` picks the
    coding, store/codings.py). fingerprint: what the shard was made from
    (:func:`~tsel_data.store.integrity.shard_fingerprint`), kept in its seal. The HDF5
    file is written under a temporary name; at the end the JSON file is written, the HDF5
    file renamed, and the seal written last, so a shard is complete exactly when its seal
    exists and matches (store/integrity.py). A failure leaves no file under a final name
    and is one DatasetError line naming the file; finished shards are never touched.
    """

    def __init__(self, out_dir: str, split: str, shard: int, n_scenes: int, attrs: dict, fingerprint: str = ""):
        self.out_dir, self.split, self.shard, self.n = out_dir, split, shard, n_scenes
        self.attrs = {k: v for k, v in attrs.items() if k != "audio_coding"}
        self.coding = attrs.get("audio_coding", AudioCoding.FLOAT32)
        self.fingerprint = fingerprint
        layout = Layout(out_dir)
        self.h5_rel, self.json_rel = shard_names(split, shard)
        self.h5_path, self.json_path = layout.shard_files(split, shard)
        self.seal_path = layout.seal_file(split, shard)
        self.tmp = f"{self.h5_path}.tmp-{os.getpid()}"
        self.kept: list[Scene] = []  # without audio and record
        self.query_rows: list[dict | None] = []
        self.hardware_rows: list[list] = []  # per scene, per receiver (_hardware_rows)
        self.descriptor_rows: list[dict | None] = []
        self.records: list[str] = []  # each scene's record, as it appears in the JSON shard
        self.entry: ShardEntry | None = None
        self._h5 = self._audio = None
        self._others: dict = {}  # further receivers' audio datasets

    def __enter__(self) -> "ShardWriter":
        try:
            os.makedirs(os.path.dirname(self.h5_path), exist_ok=True)
            for p in (self.seal_path, self.json_path, self.h5_path):
                remove_stale_tmp(p)
            if os.path.exists(self.seal_path):
                os.remove(self.seal_path)  # an old seal must never vouch for new files
        except OSError as e:
            raise write_error(self.h5_rel, e, self.out_dir, resumable=True) from None
        return self

    def add(self, scene: Scene) -> None:
        """Write one scene (the shard's scenes in order); a scene unfit to be written (NaN
        samples, levels far from its config's: store/sanity.py) stops the shard first."""
        i = len(self.kept)
        if i >= self.n:
            raise ValueError(f"shard {self.h5_rel} holds {self.n} scenes; got one more")
        check_scene(scene)
        try:
            others = scene.receivers or {}
            size = scene.audio.nbytes + sum(a.nbytes for a, _ in others.values())
            _check_space(os.path.dirname(self.h5_path), size * (1 + SPACE_MARGIN), self.h5_rel)
            if self._h5 is None:
                self._h5 = h5py.File(self.tmp, "w", track_order=False, libver=("earliest", "v110"))
                self._audio = create_audio(self._h5, self.coding, self.n, *scene.audio.shape)
                for name, (audio, _) in others.items():
                    g = self._h5.create_group(f"{RECEIVERS_GROUP}/{name}", track_order=False)
                    self._others[name] = create_audio(g, self.coding, self.n, *audio.shape)
            # through h5py: write_direct_chunk of the same chunk is faster (1.2 against 2.0 ms a
            # scene, benchmarks/bench_store.py --sections write) with the same samples, but
            # HDF5 then lays the file out otherwise, so shards' sha256 would differ from
            # every dataset made before
            fs = int(self.attrs["fs"])
            self._audio[i] = encode(scene.audio, self.coding, fs)
            for name, (audio, _) in others.items():
                self._others[name][i] = encode(audio, self.coding, fs)
        except (OSError, RuntimeError) as e:  # h5py reports some HDF5 write failures as RuntimeError
            raise write_error(self.h5_rel, e, self.out_dir, resumable=True) from None
        # keep the record as the JSON text it becomes: a fraction of its Python objects' size
        self.records.append(json.dumps(jsonable(scene.record), ensure_ascii=False, indent=1).replace("\n", "\n  "))
        self.query_rows.append(_query_row(scene))
        self.hardware_rows.append(_hardware_rows(scene.record))
        self.descriptor_rows.append(_descriptor_row(scene))
        self.kept.append(replace(scene, audio=None, record=None,
                                 receivers={k: (None, m) for k, (_, m) in (scene.receivers or {}).items()}))

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                if len(self.kept) != self.n:
                    raise ValueError(f"shard {self.h5_rel}: {len(self.kept)} scenes written, {self.n} expected")
                self._finish()
        finally:
            if self._h5 is not None:
                self._h5.close()
            if os.path.exists(self.tmp):
                os.remove(self.tmp)

    def _finish(self) -> None:
        scenes = self.kept
        js = _shard_json({"format_version": FORMAT_VERSION, "split": self.split, "shard": self.shard, **self.attrs,
                          **({"audio_coding": str(self.coding)} if self.coding != AudioCoding.FLOAT32 else {})},
                         self.records)
        what = self.h5_rel
        try:
            h = self._h5
            n_src = max(s.azimuth.shape[0] for s in scenes)
            g = h.create_group("labels")
            for key in LABEL_KEYS:
                g.create_dataset(key, data=_stack_padded([getattr(s, key) for s in scenes], n_src, np.nan, np.float32),
                                 track_times=False)
            g.create_dataset("active", data=_stack_padded([s.active for s in scenes], n_src, False, bool),
                             track_times=False)
            str_t = h5py.string_dtype("utf-8")
            h.create_dataset("query", data=np.array([s.query for s in scenes], dtype=object), dtype=str_t,
                             track_times=False)
            h.create_dataset("scene_id", data=np.array([s.scene_id for s in scenes], dtype=object), dtype=str_t,
                             track_times=False)
            if any(self.query_rows):  # absent otherwise: default shards keep their bytes
                for key, default in QUERY_COLUMNS.items():
                    vals = [(row or QUERY_COLUMNS)[key] for row in self.query_rows]
                    if isinstance(default, str):
                        h.create_dataset(key, data=np.array(vals, dtype=object), dtype=str_t, track_times=False)
                    else:
                        h.create_dataset(key, data=np.array(vals, dtype=np.float32), track_times=False)
            h.create_dataset("mic_positions", data=np.stack([s.mic_positions for s in scenes]).astype(np.float32),
                             track_times=False)
            kinds = sorted({k for s in scenes for k in (s.noise or {})})
            for kind in kinds:  # only with [noise]: other shards keep their bytes
                for col, key in ((0, "snr_db"), (1, "level_dbfs")):
                    vals = [((s.noise or {}).get(kind) or (None, None))[col] for s in scenes]
                    h.create_dataset(f"{NOISE_GROUP}/{kind}/{key}", data=np.array(
                        [np.nan if v is None else v for v in vals], dtype=np.float32), track_times=False)
            if any(r and any(r) for r in self.hardware_rows):  # only with [hardware]: other shards keep their bytes
                groups = ["", *(f"{RECEIVERS_GROUP}/{name}/" for name in scenes[0].receivers or {})]
                for k, prefix in enumerate(groups):
                    _write_hardware(h, prefix + HARDWARE_GROUP, [r[k] if k < len(r) else None
                                                                 for r in self.hardware_rows])
            if any(self.descriptor_rows):  # only with output.descriptors: other shards keep their bytes
                self._write_descriptors(h, n_src, str_t)
            for name in self._others:  # each further receiver: its audio (written above) and capsules
                g = h[f"{RECEIVERS_GROUP}/{name}"]
                g.create_dataset("mic_positions", data=np.stack([s.receivers[name][1] for s in scenes])
                                 .astype(np.float32), track_times=False)
                g.attrs["format"] = name
                g.attrs["channel_names"] = _attr(list(receiver(name).channels(n=g["mic_positions"].shape[1])))
            for k, v in sorted({"split": self.split, "shard": self.shard, **self.attrs}.items()):
                h.attrs[k] = _attr(v)
            h.attrs["frames"] = scenes[0].azimuth.shape[1]
            h.close()
            self._h5 = None
            what = self.json_rel
            _check_space(os.path.dirname(self.h5_path), len(js) * (1 + SPACE_MARGIN), what)
            atomic_write(self.json_path, js)
            json_seal = FileSeal.of(self.json_path, hashlib.sha256(js).hexdigest())
            what = self.h5_rel
            digest = _hash_and_sync(self.tmp)
            os.replace(self.tmp, self.h5_path)
            _fsync_dir(os.path.dirname(self.h5_path))
            h5_seal = FileSeal.of(self.h5_path, digest)
            what = os.path.relpath(self.seal_path, self.out_dir)
            seal = Seal(self.fingerprint, h5_seal, json_seal)
            atomic_write(self.seal_path, (json.dumps(seal.to_json()) + "\n").encode())
        except (OSError, RuntimeError) as e:
            raise write_error(what, e, self.out_dir, resumable=True) from None
        self.entry = ShardEntry(self.h5_rel, self.json_rel, len(scenes), h5_seal.sha256, json_seal.sha256)

    def _write_descriptors(self, h, n_src: int, str_t) -> None:
        """``descriptors/``: per source [N, S] the DESCRIPTOR_KEYS and ``motion``, per source
        and octave band ``t30_bands_s`` [N, S, B] (band centres in its ``bands_hz``), per
        scene ``volume_m3`` and ``floor_area_m2`` [N]; NaN (or "") where not measured."""
        rows = [r or {"sources": {}, "bands": [], "motion": [], "volume_m3": None, "floor_area_m2": None}
                for r in self.descriptor_rows]
        g = h.create_group(DESCRIPTORS_GROUP)
        for key in DESCRIPTOR_KEYS:
            a = np.full((len(rows), n_src), np.nan, np.float32)
            for i, r in enumerate(rows):
                vals = r["sources"].get(key, [])
                a[i, :len(vals)] = [_nan(v) for v in vals]
            g.create_dataset(key, data=a, track_times=False)
        bands = sorted({int(b) for r in rows for src in r["bands"] for b in src})
        a = np.full((len(rows), n_src, len(bands)), np.nan, np.float32)
        for i, r in enumerate(rows):
            for k, src in enumerate(r["bands"]):
                for j, b in enumerate(bands):
                    a[i, k, j] = _nan(src.get(str(b)))
        d = g.create_dataset("t30_bands_s", data=a, track_times=False)
        d.attrs["bands_hz"] = np.array(bands, dtype=np.int32)
        motion = np.full((len(rows), n_src), "", dtype=object)
        for i, r in enumerate(rows):
            motion[i, :len(r["motion"])] = r["motion"]
        g.create_dataset("motion", data=motion, dtype=str_t, track_times=False)
        for key in ("volume_m3", "floor_area_m2"):
            g.create_dataset(key, data=np.array([_nan(r[key]) for r in rows], np.float32), track_times=False)


def _hash_and_sync(path: str) -> str:
    """sha256 of a file just written, and the file flushed to disk: the disk writes it
    while it is hashed (read back from the page cache), so the fsync waits for little.

    Hashed once, here, in the worker that wrote it: the file's sha256 (dataset.json's
    contract) cannot be taken as the chunks are written, since HDF5 writes the superblock
    and headers before them at close; finalize trusts this seal while the file keeps its
    size and modification time."""
    with open(path, "rb") as f:
        start_writeback(f.fileno(), 0, 0)
        digest = hashlib.file_digest(f, "sha256").hexdigest()
        os.fsync(f.fileno())
    return digest


def _write_hardware(h, group: str, rows: list) -> None:
    """One receiver's :data:`HARDWARE_COLUMNS` of every scene into ``group`` (NaN / 0 for
    a scene without hardware)."""
    if not any(rows):
        return
    n_ch = max(len(r["gain_db"]) for r in rows if r)
    for key, dtype in HARDWARE_COLUMNS.items():
        scalar = key in ("sensitivity_dbfs", "highpass_order")
        fill = 0 if np.issubdtype(dtype, np.integer) else np.nan
        data = np.full((len(rows),) if scalar else (len(rows), n_ch), fill, dtype=dtype)
        for i, r in enumerate(rows):
            if r:
                data[i] = r[key] if scalar else np.asarray(r[key], dtype=np.float64)
        h.create_dataset(f"{group}/{key}", data=data, track_times=False)


def _shard_json(header: dict, records: list[str]) -> bytes:
    """The JSON shard: ``header`` then ``"scenes": [...]``, laid out as ``json.dumps(doc,
    indent=1)`` lays it out (the records come already serialised, indented for depth 2)."""
    head = json.dumps(jsonable({**header, "scenes": []}), ensure_ascii=False, indent=1)
    assert head.endswith('"scenes": []\n}')
    body = "[\n  " + ",\n  ".join(records) + "\n ]" if records else "[]"
    return (head[: -len("[]\n}")] + body + "\n}\n").encode("utf-8")


def _check_space(folder: str, need: float, what: str) -> None:
    """Refuse, in one line, a write the disk cannot hold: a write that runs out of space
    mid-file can take the HDF5 library down with it."""
    free = shutil.disk_usage(folder).free
    if free < need:
        raise OSError(errno.ENOSPC, f"No space left: about {need / 1e6:.1f} MB needed, {free / 1e6:.1f} MB free",
                      what)


def _stack_padded(arrays, n_src, fill, dtype) -> np.ndarray:
    n_frames = arrays[0].shape[1]
    out = np.full((len(arrays), n_src, n_frames), fill, dtype=dtype)
    for i, a in enumerate(arrays):
        out[i, : a.shape[0]] = a
    return out


def _attr(v):
    if isinstance(v, dict):  # HDF5 attributes hold no tables: the JSON text
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        if all(isinstance(x, str) for x in v):
            return np.array(v, dtype=h5py.string_dtype("utf-8"))
        return np.asarray(v)
    return v
