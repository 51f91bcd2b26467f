"""The WebDataset sample layout of a scene, both directions: the members a scene becomes
and the tar headers they go under (the export writes them, ``tsel_data.export.webdataset``),
and the tar, ``.npy`` and sample readers that turn an export back into the reader's scenes
(the stream, ``tsel_data.tools.streaming``).

A sample is the members of one scene id (WebDataset's key), in this order:

- ``{key}.audio.npy``: float32 [C, T] (float32 datasets) or int16 [C, T] (int16 datasets:
  ``sample / 32768``); ``{key}.audio.flac`` instead for flac datasets (16-bit, [T, C]);
- ``{key}.json``: the labels and the query (:data:`SAMPLE_KEYS`; NaN as null);
- ``{key}.record.json``: the scene's record (docs/format.md, "JSON shard").

The ``webdataset`` package reads the shards as they are (``wds.WebDataset(urls).decode()``),
so does ``datasets.load_dataset("webdataset", ...)`` (``.npy`` keeps every channel).
"""
from __future__ import annotations

import json
import os
import re
import tarfile

import numpy as np

from ..choices import AudioCoding
from ..core.files import check_input, name_problem
from ..errors import DatasetError
from ..store.codings import INT16_SCALE, decode
from ..store.extents import Extent
from ..store.records import SceneRecord
from ..store.scene import Scene
from .coding import decode_samples, flac_bytes, npy_array, npy_header, stored_samples

_NPY_HEADER = re.compile(r"\{'descr': '(?P<descr>[^']+)', 'fortran_order': (?P<fortran>True|False), "
                         r"'shape': \((?P<shape>[0-9, ]*)\), \}")
INDEX_FILE = "index.json"
INDEX_KIND = "tsel-data webdataset"
INDEX_VERSION = 1
BLOCK = 512
# the keys of a sample's JSON, in order
SAMPLE_KEYS = ("scene_id", "split", "index", "query", "query_type", "query_relation", "pairing", "fs", "label_hop",
               "format", "channel_names", "audio_coding", "audio_scale", "azimuth", "elevation", "distance",
               "active", "mic_positions")


def shard_name(split: str, k: int) -> str:
    return f"{split}/{split}-{k:06d}.tar"


def audio_member(coding: str) -> str:
    """The member name (after the key) of a sample's audio."""
    return "audio.flac" if coding == AudioCoding.FLAC else "audio.npy"


class _Json(str):
    """JSON text dropped into a document as it is (see :func:`sample_bytes`)."""


def _labels(a: np.ndarray) -> _Json:
    """A label array [S, F] as JSON text, NaN as null, the text ``json.dumps`` gives:
    numbers only, so the text replace is safe (20 times faster than mapping every value
    in Python). Each distinct value is formatted once (by its bits: -0.0 stays itself), as
    a label track repeats its values (a static source has one direction): 3.7x faster on
    the demo scenes, 2x on moving ones."""
    a = np.asarray(a)
    if a.ndim != 2 or a.dtype.kind != "f" or a.dtype.itemsize not in (4, 8):
        return _Json(json.dumps(a.tolist()).replace("NaN", "null"))
    bits, inv = np.unique(a.view(np.uint32 if a.dtype.itemsize == 4 else np.uint64).ravel(), return_inverse=True)
    text = json.dumps(bits.view(a.dtype).tolist())[1:-1].replace("NaN", "null").split(", ")
    words, n = [text[i] for i in inv.tolist()], a.shape[1]
    return _Json("[" + ", ".join("[" + ", ".join(words[r * n:(r + 1) * n]) + "]" for r in range(a.shape[0])) + "]")


def sample_json(scene: Scene, coding: str, channel_names) -> dict:
    """A scene's labels and query as the sample's JSON (float32 values as exact doubles;
    ``query_relation`` is ``""`` for a caption, as in the HDF5 shards, so every sample has
    the same types). The label arrays are :class:`_Json` text: :func:`sample_bytes`."""
    return {"scene_id": scene.scene_id, "split": scene.split, "index": int(scene.index), "query": scene.query,
            "query_type": scene.query_type, "query_relation": scene.query_relation or "", "pairing": scene.pairing,
            "fs": scene.fs, "label_hop": scene.label_hop, "format": scene.format, "channel_names": list(channel_names),
            "audio_coding": str(coding), "audio_scale": 1.0 if coding == AudioCoding.FLOAT32 else 1.0 / INT16_SCALE,
            "azimuth": _labels(scene.azimuth), "elevation": _labels(scene.elevation),
            "distance": _labels(scene.distance), "active": _Json(json.dumps(scene.active.tolist())),
            "mic_positions": _Json(json.dumps(scene.mic_positions.tolist()))}


def sample_bytes(doc: dict) -> bytes:
    """The sample's JSON: plain values through json (a run of them in one call: a call
    costs more than its small values), :class:`_Json` text as it is."""
    parts, run = [], {}
    for k, v in doc.items():
        if isinstance(v, _Json):
            if run:
                parts.append(json.dumps(run, ensure_ascii=False)[1:-1])
                run = {}
            parts.append(f"{json.dumps(k)}: {v}")
        else:
            run[k] = v
    if run:
        parts.append(json.dumps(run, ensure_ascii=False)[1:-1])
    return ("{" + ", ".join(parts) + "}").encode("utf-8")


def sample_members(scene: Scene, coding: str, channel_names, extent: Extent | None = None) -> list[tuple[str, list]]:
    """[(member name, [chunks])] of one scene's sample: chunks are bytes-like, or the
    :class:`~tsel_data.store.extents.Extent` of the scene's samples in its shard."""
    key = scene.scene_id
    if extent is not None:
        audio = [npy_header(extent.dtype, extent.shape), extent]
    elif coding == AudioCoding.FLAC:
        audio = [flac_bytes(scene.audio, scene.fs)]
    else:
        samples = np.ascontiguousarray(stored_samples(scene.audio, coding))
        audio = [npy_header(samples.dtype, samples.shape), memoryview(samples).cast("B")]
    members = [(f"{key}.{audio_member(coding)}", audio),
               (f"{key}.json", [sample_bytes(sample_json(scene, coding, channel_names))])]
    if scene.record is not None:
        members.append((f"{key}.record.json", [json.dumps(scene.record.to_json(), ensure_ascii=False)
                                               .encode("utf-8")]))
    return members


def member_bytes(chunks) -> int:
    """Bytes a member takes in a tar: its header block and its data padded to blocks."""
    size = sum(len(c) for c in chunks)
    return BLOCK + size + (-size % BLOCK)


def _ustar_template() -> bytes:
    info = tarfile.TarInfo("x")
    info.mode, info.mtime = 0o644, 0
    return info.tobuf(tarfile.PAX_FORMAT, "utf-8", "surrogateescape")


_TEMPLATE = _ustar_template()
# the checksum of the fields a member does not change (the checksum's own counts as spaces)
_FIXED_SUM = sum(_TEMPLATE[100:124]) + sum(_TEMPLATE[136:148]) + 8 * 0x20 + sum(_TEMPLATE[156:])


def header_block(name: str, size: int) -> bytes:
    """The tar header of a regular member (mode 644, mtime 0, no owner), the bytes
    ``tarfile.TarInfo.tobuf`` gives in PAX format: for a short ASCII name and a size below
    8 GiB a ustar block patched from a template (tobuf builds it field by field, 18 µs a
    member against 1), tarfile's own header otherwise (a PAX record for a long or non-ASCII name)."""
    raw = name.encode("ascii", "surrogateescape") if name.isascii() else None
    if raw is None or len(raw) > 100 or not 0 <= size < 8 ** 11:
        info = tarfile.TarInfo(name)
        info.size, info.mode, info.mtime = size, 0o644, 0
        return info.tobuf(tarfile.PAX_FORMAT, "utf-8", "surrogateescape")
    digits = b"%011o\0" % size
    checksum = _FIXED_SUM + sum(raw) + sum(digits)
    return b"".join((raw, bytes(100 - len(raw)), _TEMPLATE[100:124], digits, _TEMPLATE[136:148],
                     b"%06o\0 " % checksum, _TEMPLATE[156:]))


def iter_members(path: str):
    """(name, data) of every file in a tar, in order. ``.npy`` members come as their
    arrays, read straight into place (writable, no copy); others as bytes. PAX and GNU
    long names are followed; a damaged or cut header is a DatasetError naming the file."""
    pending = None
    check_input(path, DatasetError, "a shard of a WebDataset export is a tar file")  # a FIFO never ends
    with open(path, "rb", buffering=1 << 16) as f:
        while True:
            head = f.read(BLOCK)
            if len(head) < BLOCK or not head.strip(b"\0"):
                return
            try:
                own, size, kind = tar_header(head)
            except ValueError as e:
                raise DatasetError(f"{path}: damaged tar header at byte {f.tell() - BLOCK} ({e}); export the "
                                   f"shard again") from None
            name, regular = pending or own, kind in _REGULAR
            if regular and name.endswith(".npy"):
                data = read_npy(f, size, path)
            else:
                data = f.read(size)
                if len(data) != size:
                    raise DatasetError(f"{path}: ends inside {own}; the shard is truncated: export it again")
            f.seek(-size % BLOCK, os.SEEK_CUR)
            if kind == tarfile.XHDTYPE:
                pending = _pax_path(data) or pending
            elif kind == tarfile.GNUTYPE_LONGNAME:
                pending = data.rstrip(b"\0").decode("utf-8", "surrogateescape")
            elif regular:
                yield name, data
                pending = None


_REGULAR = frozenset(tarfile.REGULAR_TYPES)


def tar_header(head: bytes) -> tuple[str, int, bytes]:
    """(name, size, type) of a 512-byte tar header, as ``tarfile.TarInfo.frombuf`` gives
    them (the ustar prefix joined, base-256 sizes, a V7 directory), reading only those:
    frombuf parses every field, 22 µs a member, a tenth of streaming a scene. ValueError
    when the checksum or the size is damaged."""
    unsigned = sum(head) - sum(head[148:156]) + 256  # the checksum field counts as 8 spaces
    stored = _number(head[148:156])
    if stored != unsigned and stored != unsigned - 256 * sum(1 for b in head[:148] + head[156:] if b > 127):
        raise ValueError("bad checksum")  # tarfile accepts the sum of unsigned or of signed bytes
    kind, name = head[156:157], _text(head[:100])
    if kind == tarfile.AREGTYPE and name.endswith("/"):
        kind = tarfile.DIRTYPE
    if kind == tarfile.DIRTYPE:
        name = name.rstrip("/")
    prefix = _text(head[345:500])
    if prefix and kind not in _GNU_TYPES:
        name = f"{prefix}/{name}"
    return name, _number(head[124:136]), kind


_GNU_TYPES = frozenset(tarfile.GNU_TYPES)


def _text(field: bytes) -> str:
    end = field.find(b"\0")
    return (field if end < 0 else field[:end]).decode("utf-8", "surrogateescape")


def _number(field: bytes) -> int:
    """A header number: octal text, or base-256 (GNU, first byte 0o200 or 0o377)."""
    if field[0] in (0o200, 0o377):
        n = int.from_bytes(field[1:], "big")
        return n - (256 ** (len(field) - 1)) if field[0] == 0o377 else n
    end = field.find(b"\0")
    text = (field if end < 0 else field[:end]).strip()
    try:
        return int(text or b"0", 8)
    except ValueError:
        raise ValueError(f"invalid number {field!r}") from None


def read_npy(f, size: int, path: str) -> np.ndarray:
    """A ``.npy`` member of ``size`` bytes at ``f``'s position, read into a new array."""
    head = f.read(10)
    if head[:6] != b"\x93NUMPY" or len(head) < 10:
        raise DatasetError(f"{path}: a .npy member is not a numpy file; export the shard again")
    wide = head[6] >= 2  # version 2 headers count their length in 4 bytes
    if wide:
        head += f.read(2)
    hlen = int.from_bytes(head[8:12] if wide else head[8:10], "little")
    dtype, shape = npy_header_fields(f.read(hlen), path)
    a = np.empty(shape, dtype=dtype)
    if f.readinto(memoryview(a).cast("B")) != a.nbytes or len(head) + hlen + a.nbytes != size:
        raise DatasetError(f"{path}: a .npy member is cut short; the shard is truncated: export it again")
    return a


def npy_header_fields(text: bytes, path: str) -> tuple[np.dtype, tuple]:
    """(dtype, shape) of a C-ordered array's ``.npy`` header (a Python literal dict)."""
    m = _NPY_HEADER.match(text.decode("latin1"))
    if m is None or m.group("fortran") != "False":
        raise DatasetError(f"{path}: a .npy member has a header this reader does not take: {text[:80]!r}")
    shape = tuple(int(v) for v in m.group("shape").replace(",", " ").split())
    return np.dtype(m.group("descr")), shape


def _pax_path(data) -> str | None:
    """The ``path`` record of a PAX header block ("LEN key=value\\n" records)."""
    pos, raw = 0, data
    while pos < len(raw):
        space = raw.find(b" ", pos)
        if space < 0:
            return None
        length = int(raw[pos:space])
        key, _, value = raw[space + 1:pos + length - 1].partition(b"=")
        if key == b"path":
            return value.decode("utf-8", "surrogateescape")
        pos += length
    return None


def split_key(name: str) -> tuple[str, str]:
    """WebDataset's (key, member): the base name up to its first dot, and the rest."""
    folder, _, base = name.rpartition("/")
    stem, _, rest = base.partition(".")
    return (f"{folder}/{stem}" if folder else stem), rest


def iter_samples(path: str):
    """{member: data} of every sample of a tar, in order (members of one key together)."""
    key, sample = None, {}
    for name, data in iter_members(path):
        k, member = split_key(name)
        if k != key and sample:
            yield key, sample
            sample = {}
        key = k
        sample[member] = data
    if sample:
        yield key, sample


def _float32(rows) -> np.ndarray:
    return np.array(rows, dtype=np.float32).reshape(len(rows), -1)


def scene_of_sample(key: str, sample: dict, with_record: bool = True) -> Scene:
    """The reader's :class:`~tsel_data.store.scene.Scene` of a sample (audio float32
    [C, T], every label, the record when present and ``with_record``)."""
    try:
        meta = json.loads(sample["json"])
        if "audio.npy" in sample:
            a = sample["audio.npy"]
            audio = decode_samples(a if isinstance(a, np.ndarray) else npy_array(a))
        else:
            audio = decode(np.frombuffer(sample["audio.flac"], dtype=np.uint8), AudioCoding.FLAC)
        rec = sample.get("record.json") if with_record else None
        return Scene(scene_id=meta["scene_id"], split=meta["split"], index=int(meta["index"]), query=meta["query"],
                     audio=audio, azimuth=_float32(meta["azimuth"]), elevation=_float32(meta["elevation"]),
                     distance=_float32(meta["distance"]), active=np.array(meta["active"], dtype=bool)
                     .reshape(len(meta["active"]), -1), mic_positions=np.array(meta["mic_positions"],
                                                                                dtype=np.float32).reshape(-1, 3),
                     fs=int(meta["fs"]), label_hop=float(meta["label_hop"]), format=meta["format"],
                     record=None if rec is None else SceneRecord.from_json(json.loads(rec)),
                     query_type=meta["query_type"], query_relation=meta["query_relation"] or None,
                     pairing=meta["pairing"])
    except (KeyError, ValueError, TypeError) as e:
        raise DatasetError(f"sample {key!r}: not a tsel-data sample ({type(e).__name__}: {e}); read it with the "
                           f"webdataset package, or export it again") from None


def read_index(folder: str) -> dict:
    """``index.json`` of a WebDataset export (DatasetError when absent or not ours)."""
    path = os.path.join(folder, INDEX_FILE)
    check_input(path, DatasetError, "export again")
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except FileNotFoundError:
        raise DatasetError(f"{path} not found: {folder} is not a WebDataset export of tsel-data (`tsel export "
                           f"webdataset DIR --out {folder}` makes one), or give the shard files") from None
    except (OSError, ValueError, RecursionError) as e:
        raise DatasetError(f"{path} is unreadable ({e}); export again") from None
    if not isinstance(doc, dict) or doc.get("kind") != INDEX_KIND:
        raise DatasetError(f"{path} is not the index of a tsel-data WebDataset export")
    try:  # the shards it names stay in the export
        for split, v in doc["splits"].items():
            for s in v["shards"]:
                why = name_problem(s["file"])
                if why:
                    raise DatasetError(f"{path}: split {split}: shard {s['file']!r} {why}; the index was edited: "
                                       f"export again")
                int(s["scenes"])
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise DatasetError(f"{path} is not a complete index ({type(e).__name__}: {e}); export again") from None
    return doc
