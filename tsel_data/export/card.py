"""The dataset card: ``README.md`` with the Hugging Face Hub's YAML header, written with
every export and by ``tsel export card`` for any dataset.

What it says, all from the dataset itself (``dataset.json``, the records, ``tsel stats``):
what the dataset is and holds (splits, receiver, channels, coding), the source corpora
and what their licences ask, how labels and queries are defined (the conventions block
of ``dataset.json``; docs/format.md is the contract), the distributions as measured,
known limits of the simulation, how to rebuild it from a recipe release, the citations,
and the config with its hash.
"""
from __future__ import annotations

import hashlib
import json

from ..core.version import __version__
from ..errors import TselError
from ..receivers import receiver
from ..tools.stats import dataset_stats, format_text, plot_stats

CARD_FILE = "README.md"
FIGURE_FILE = "stats.png"

BUILTIN_DEMO = "builtin:demo"
# corpus.format -> (name, where its audio and captions come from and what their licences ask)
CORPORA = {
    "audiocaps": ("AudioCaps", "audio: the soundtracks of YouTube videos listed by AudioSet, each under its "
                  "uploader's terms (not redistributable by you: publish a recipe release instead); captions: the "
                  "AudioCaps annotations (Kim et al., NAACL 2019), under the licence of their repository"),
    "clotho": ("Clotho", "audio: Freesound clips, each under its own licence (mostly Creative Commons with "
               "attribution), named per file in Clotho's metadata CSVs; captions: Clotho (Drossos et al., ICASSP 2020)"),
    "wavcaps": ("WavCaps", "audio from FreeSound, BBC Sound Effects, SoundBible and AudioSet, each under its "
                "source's terms; captions: WavCaps (Mei et al., 2023): read its terms of use before publishing"),
    "plain": ("own recordings or a corpus of your own", "the licence its owner gives: state it here before "
              "publishing"),
    "auto": ("a captioned corpus (format detected from its manifests)", "the licences of that corpus: state them "
             "here before publishing"),
}
DEMO_CORPUS = ("tsel-data's built-in demo corpus", "synthetic sounds and captions made by tsel-data (no recordings); "
               "MIT, as tsel-data")

PAPER_BIBTEX = """@misc{zhao2024tsel,
  title = {Text-Queried Target Sound Event Localization},
  author = {Zhao, Jinzheng and Qian, Xinyuan and Xu, Yong and Liu, Haohe and Cao, Yin and Berghi, Davide and
            Wang, Wenwu},
  year = {2024},
  eprint = {2406.16058},
  archivePrefix = {arXiv}
}"""
# as CITATION.cff says (a test holds them together)
TOOL_AUTHORS, TOOL_YEAR = "The tsel-data developers", 2026
TOOL_BIBTEX = f"""@software{{tsel_data,
  title = {{tsel-data: datasets for text-queried target sound event localization}},
  author = {{{{{TOOL_AUTHORS}}}}},
  year = {{{TOOL_YEAR}}},
  version = {{{__version__}}},
  license = {{MIT}}
}}"""

LIMITS = (
    "Simulated rooms are empty shoeboxes with uniform walls (image sources for the early part, a modelled late "
    "tail): no furniture, no diffraction, and sources radiate equally in all directions.",
    "RIR-bank rooms have only the positions the bank measured; a moving source moves by crossfading between "
    "them.",
    "`active` comes from the dry clip's frame energy against `activity_threshold_db` of its loudest frame, not "
    "from annotation.",
    "A caption describes its whole clip, not the part a scene uses; a query may name a sound that is silent in "
    "some frames.",
    "The ambiguity guard (`scene.caption_similarity`) compares captions as text: two clips may still sound "
    "alike.",
    "Additive sources are added unspatialised (no position, NaN labels).",
)


def config_hash(config: dict) -> str:
    """sha256 of the resolved config as canonical JSON (sorted keys, no spaces)."""
    return hashlib.sha256(json.dumps(config, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
                          .encode("utf-8")).hexdigest()


def corpus_of(config: dict) -> tuple[str, str]:
    """(name, licence note) of the dataset's clip corpus."""
    corpus = config.get("corpus") or {}
    if corpus.get("dir") == BUILTIN_DEMO:
        return DEMO_CORPUS
    return CORPORA.get(str(corpus.get("format", "auto")), CORPORA["auto"])


def rooms_of(config: dict) -> tuple[str, str]:
    """(what the rooms are, licence note)."""
    room = config.get("room") or {}
    bank = str(room.get("bank") or "")
    if not bank:
        return (f"simulated shoebox rooms (`room.rir_method` {room.get('rir_method', 'hybrid')})", "simulated by tsel-data: "
                "nothing to license")
    if bank == "builtin:demo-bank":
        return "tsel-data's built-in demo RIR bank (simulated)", "simulated by tsel-data: nothing to license"
    name = bank.rstrip("/").rsplit("/", 1)[-1]
    if "tau" in name.lower():
        return (f"measured RIRs of TAU-SRIR DB ({name}; Politis et al.)", "the licence of its Zenodo record; cite it")
    return f"the RIR bank {name}", "the licence its makers give; state it here before publishing"


def size_category(n: int) -> str:
    """The Hub's ``size_categories`` value for ``n`` scenes."""
    edges = ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"), (1_000_000, "100K<n<1M"))
    return next((label for edge, label in edges if n < edge), "1M<n<10M")


def yaml_dump(doc, indent: int = 0) -> str:
    """A small YAML writer for the card header (dicts, lists, strings, numbers, bools):
    strings as JSON strings, which YAML reads as they are."""
    pad = " " * indent
    lines = []
    for key, value in doc.items():
        if isinstance(value, dict):
            lines.append(f"{pad}{key}:")
            lines.append(yaml_dump(value, indent + 2))
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            lines.append(f"{pad}{key}:")
            for item in value:
                body = yaml_dump(item, indent + 2).splitlines()
                lines.append(f"{pad}- {body[0].lstrip()}")
                lines.extend(f"{pad}  {line[indent + 2:]}" for line in body[1:])
        elif isinstance(value, list):
            lines.append(f"{pad}{key}:")
            lines.extend(f"{pad}- {_scalar(v)}" for v in value)
        else:
            lines.append(f"{pad}{key}: {_scalar(value)}")
    return "\n".join(lines)


def _scalar(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    return json.dumps(str(v), ensure_ascii=False)


def header(doc, yaml_extra: dict | None = None) -> dict:
    """The YAML header: name, licence, task, tags, size, and what the export adds (``configs``)."""
    n = sum(doc.counts.values())
    licence = "mit" if corpus_of(doc.config) is DEMO_CORPUS else "other"
    head = {"pretty_name": f"{doc.config.get('name') or 'tsel-data'} (text-queried sound event localization)",
            "license": licence, "language": ["en"], "task_categories": ["audio-classification"],
            "tags": ["sound-event-localization", "spatial-audio", "text-queried", "multichannel", "tsel-data",
                     doc.format], "size_categories": [size_category(n)]}
    return {**head, **(yaml_extra or {})}


def hf_loading(doc, splits: list) -> list:
    """The card's "Load it" section of an ``hf`` export: Python that runs with stock
    ``datasets`` (no audio codec: the Audio column is not decoded) and soundfile, in the
    export's folder (tests/export/test_export_formats.py runs it)."""
    split = "test" if "test" in splits else splits[0]
    coding = str(doc.raw.get("audio_coding", "float32"))
    duration = (doc.config.get("audio") or {}).get("duration")
    frames = int(round(float(duration) * doc.fs)) if isinstance(duration, (int, float)) else "T"
    shape = f"[{len(doc.channel_names)}, {frames}]"
    if coding == "float32":
        dtype, read, numpy = "float32", 'np.asarray(row["samples"], dtype=np.float32)', "float32"
    else:
        dtype, read = "int16", 'np.asarray(row["samples"], dtype=np.float32) / 32768  # stored as int16'
        numpy = "integers (int64: datasets widens them), to divide by 32768"
    audio_file = "FLAC" if coding == "flac" else "WAV"
    return ["## Load it", "",
            "With `datasets` alone, no audio codec: every scene's samples are in `samples` "
            f"({dtype} {shape}, every channel, fixed-size lists any Parquet reader reads), and its {audio_file} "
            'file in `audio`, whose feature is `Audio(decode=False)`: `row["audio"]` is `{"bytes", "path"}`, '
            "which soundfile reads whole. (`datasets` 4 and later decode an `Audio` column with torchcodec, one "
            "more install, and `datasets` 3 down-mixes it to mono: leave it undecoded.)", "",
            "```python", "import io", "", "import numpy as np", "import soundfile as sf",
            "from datasets import load_dataset", "",
            f'# from the Hub: load_dataset("OWNER/NAME", split="{split}"); a copy: load_dataset("/path/to/it", '
            f'split="{split}")',
            f'ds = load_dataset("parquet", data_files={{"{split}": "data/{split}/*.parquet"}}, split="{split}")',
            "row = ds[0]",
            f"samples = {read}",
            'audio, fs = sf.read(io.BytesIO(row["audio"]["bytes"]), dtype="float32", always_2d=True)',
            f'assert fs == row["fs"] and np.array_equal(audio.T, samples)  # the {audio_file} file: the same '
            "samples",
            'print(row["scene_id"], repr(row["query"]), samples.shape, np.asarray(row["azimuth"]).shape)',
            "```", "",
            f'`ds.with_format("numpy")` gives arrays (`samples` {shape}, {numpy}; `azimuth`, `elevation`, '
            '`distance`, `active` [S, F], source 0 the target); `ds.with_format("torch", columns=[...])` '
            "tensors. The record of every scene and every source: the configs `scenes` and `sources` "
            f'(`load_dataset("OWNER/NAME", "sources", split="{split}")`; here, the files '
            f"`metadata/{split}/scenes.parquet` and `sources.parquet`).", ""]


def card_text(root: str, doc, export: str = "card", splits=None, yaml_extra: dict | None = None,
              figure: str | None = None, stats: dict | None = None, sections: list | None = None) -> str:
    """The card of the dataset ``root`` (``doc``: its DatasetDoc) for an export of kind
    ``export`` holding ``splits`` (default: all); ``figure``: the statistics PNG beside it;
    ``sections``: lines of Markdown the export adds (what its own files hold)."""
    splits = list(splits) if splits is not None else list(doc.splits)
    stats = dataset_stats(root) if stats is None else stats
    cfg = doc.config
    corpus, corpus_licence = corpus_of(cfg)
    rooms, rooms_licence = rooms_of(cfg)
    audio = cfg.get("audio") or {}
    try:
        spec = receiver(doc.format)
        receiver_line = f"`{doc.format}`: {spec.summary}"
    except TselError:
        receiver_line = f"`{doc.format}`"
    coding = doc.raw.get("audio_coding", "float32")
    out = ["---", yaml_dump(header(doc, yaml_extra)), "---", "",
           f"# {cfg.get('name') or 'tsel-data dataset'}", "",
           "Scenes for **text-queried target sound event localization**: a multichannel recording of a room in "
           "which several sound events play at once, a free-text query that describes one of them (the target), "
           "and the direction of arrival of every source for every label frame. Made with tsel-data "
           f"{doc.raw.get('version', __version__)} (`{export}` export).", "",
           "## What it holds", "",
           "| split | scenes | in this export |", "|---|---|---|"]
    out += [f"| {s} | {doc.counts[s]} | {'yes' if s in splits else 'no'} |" for s in doc.splits]
    out += ["",
            f"- receiver: {receiver_line}; {len(doc.channel_names)} channels: "
            + ", ".join(f"`{c}`" for c in doc.channel_names),
            f"- audio: {doc.fs} Hz, {audio.get('duration', '?')} s per scene, stored as {coding} (all channels)",
            f"- labels: azimuth, elevation, distance and activity per source and {doc.label_hop} s frame; "
            "source 0 is the target",
            f"- clips: {corpus}", f"- rooms: {rooms}", ""]
    if export == "hf":
        out += hf_loading(doc, splits)
    out += list(sections or ())
    out += ["## Sources and licences", "",
            "| part | what | licence |", "|---|---|---|",
            f"| clips | {corpus} | {corpus_licence} |", f"| rooms | {rooms} | {rooms_licence} |",
            "| labels, queries, mixtures | made by tsel-data from the above | as the clips they are made of |", "",
            "## Labels and queries", "",
            "Every label is in the array frame (docs/format.md of tsel-data is the contract for every field):", "",
            "| what | convention |", "|---|---|"]
    out += [f"| {k} | {v} |" for k, v in (doc.raw.get("conventions") or {}).items()]
    out += ["", "The query describes source 0: one of its captions, or a relation such as the loudest or the "
            "nearest source (docs/queries.md of tsel-data). `query_type` says which.", "",
            "## Distributions as measured", "", "From `tsel stats` (labels and records; no audio is read):", "",
            "```", format_text(stats), "```", ""]
    if figure:
        out += [f"![statistics per split]({figure})", ""]
    out += ["## Known limits", ""] + [f"- {line}" for line in LIMITS]
    out += ["", "## Rebuild it", "",
            "A recipe release (`tsel export recipes DIR --out REL`: the plan, the config and per-scene checksums, "
            "no audio) rebuilds this dataset bit for bit from your own copy of the corpus, and says scene by "
            "scene what came out identical, what differs (and which clip), and what could not be built:", "",
            "```bash", "tsel generate --from REL --corpus-dir MY_COPY --out DIR", "tsel check DIR --release REL",
            "```", "", "## Citation", "", "```bibtex", PAPER_BIBTEX, "", TOOL_BIBTEX, "```", "",
            "## Config", "", f"sha256 of the resolved config (canonical JSON): `{config_hash(cfg)}`, seed "
            f"{doc.raw.get('seed', 0)}.", "", "<details><summary>the config</summary>", "", "```json",
            json.dumps(cfg, indent=1, ensure_ascii=False), "```", "", "</details>", ""]
    return "\n".join(out)


def draw_figure(root: str, path: str, stats: dict | None = None) -> str:
    """The ``tsel stats`` histograms of the dataset, as a PNG."""
    return plot_stats(dataset_stats(root) if stats is None else stats, path)
