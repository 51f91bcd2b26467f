"""Sound-event classes of the recorded SELD datasets, each with caption wordings a query
can use: index -> name -> captions.

The built-in tables follow each dataset's own class list (its README: STARSS22/23 and the
DCASE 2025 stereo set share STARSS23's 13 classes; TAU-NIGENS Spatial Sound Events 2020
has 14 and 2021 has 12, from the NIGENS database). The wordings are written for this
toolkit in the style of AudioCaps captions (a subject and a verb in the present tense),
several per class so queries vary, and each describes its own class only: "A woman speaks"
never fits a man's speech, and "Recorded music plays" not someone playing an instrument,
since scenes are told apart by class (docs/recorded.md).

Any other ontology is a small file (:func:`read_ontology`): CSV ``index,name,captions``
with the captions separated by ``|``, or JSON ``{"0": {"name": ..., "captions": [...]}}``.
"""
from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass

from ..errors import ConfigError
from ..core.files import check_input


@dataclass(frozen=True)
class SoundClass:
    index: int
    name: str
    captions: tuple[str, ...]


Ontology = dict[int, SoundClass]


def _table(rows) -> Ontology:
    return {k: SoundClass(k, name, tuple(caps)) for k, (name, caps) in enumerate(rows)}


_FEMALE_SPEECH = ("A woman speaks", "A woman is talking", "A female voice speaks", "A woman talks to someone nearby")
_MALE_SPEECH = ("A man speaks", "A man is talking", "A male voice speaks", "A man talks to someone nearby")
_FOOTSTEPS = ("Footsteps walk across the floor", "Someone is walking", "A person walks by",
              "Footsteps are heard on the floor")
_PHONE = ("A telephone rings", "A phone is ringing", "A phone rings loudly", "A telephone ring tone plays")

# STARSS22 / STARSS23 (DCASE 2022-2024 task 3) and the DCASE 2025 stereo set
STARSS = _table([
    ("Female speech, woman speaking", _FEMALE_SPEECH),
    ("Male speech, man speaking", _MALE_SPEECH),
    ("Clapping", ("People clap", "Someone claps their hands", "Hands clap repeatedly", "Clapping is heard")),
    ("Telephone", _PHONE),
    ("Laughter", ("Someone laughs", "A person is laughing", "People laugh", "Laughter breaks out")),
    ("Domestic sounds", ("Household objects clatter", "Dishes and objects are handled in a room",
                         "A household appliance is running", "Objects are moved around a room")),
    ("Walk, footsteps", _FOOTSTEPS),
    ("Door, open or close", ("A door opens and closes", "A door is shut", "A door creaks open",
                             "Someone closes a door")),
    ("Music", ("Recorded music plays", "Music plays from a speaker", "A song plays from a speaker",
               "Recorded music is playing in the room")),
    ("Musical instrument", ("Someone plays a musical instrument", "An instrument is being played by hand",
                            "A person plays an instrument", "Notes are played on an instrument")),
    ("Water tap, faucet", ("Water runs from a tap", "A faucet is running", "Water pours from a faucet",
                           "A tap is turned on and water flows")),
    ("Bell", ("A bell rings", "A bell is ringing", "A small bell chimes", "Someone rings a bell")),
    ("Knock", ("Someone knocks", "Knocking on a door", "A person knocks on wood", "Knocks are heard")),
])

_NIGENS = {
    "alarm": ("An alarm goes off", "An alarm is beeping", "An alarm sounds", "A loud alarm rings"),
    "crying baby": ("A baby cries", "An infant is crying", "A baby wails", "A small child cries loudly"),
    "crash": ("Something crashes", "Objects crash to the floor", "A loud crash is heard", "Something falls and breaks"),
    "barking dog": ("A dog barks", "A dog is barking", "A dog barks repeatedly", "Barking of a dog"),
    "running engine": ("An engine runs", "An engine is idling", "A motor is running", "An engine hums steadily"),
    "female scream": ("A woman screams", "A woman is screaming", "A female voice screams", "A woman shrieks"),
    "female speech": _FEMALE_SPEECH,
    "burning fire": ("A fire burns", "Fire is crackling", "Flames crackle", "A fire is burning"),
    "footsteps": _FOOTSTEPS,
    "knocking on door": ("Someone knocks on a door", "Knocking on a door", "A door is knocked on",
                         "A person knocks at the door"),
    "male scream": ("A man screams", "A man is screaming", "A male voice screams", "A man shouts in alarm"),
    "male speech": _MALE_SPEECH,
    "ringing phone": _PHONE,
    "piano": ("A piano is played", "Someone plays the piano", "Piano notes are played", "A piano plays a melody"),
}

# TAU-NIGENS Spatial Sound Events 2020 (DCASE 2020 task 3) and 2021 (DCASE 2021 task 3)
TAU_NIGENS_2020 = _table([(n, _NIGENS[n]) for n in (
    "alarm", "crying baby", "crash", "barking dog", "running engine", "female scream", "female speech",
    "burning fire", "footsteps", "knocking on door", "male scream", "male speech", "ringing phone", "piano")])
TAU_NIGENS_2021 = _table([(n, _NIGENS[n]) for n in (
    "alarm", "crying baby", "crash", "barking dog", "female scream", "female speech", "footsteps",
    "knocking on door", "male scream", "male speech", "ringing phone", "piano")])


def read_ontology(path: str) -> Ontology:
    """An ontology file: CSV (``index,name,captions``, a header row, captions joined by
    ``|``) or JSON (``{"INDEX": {"name": NAME, "captions": [...]}}``). ConfigError naming
    the file and row when it is not one."""
    if os.path.isdir(path):
        raise ConfigError(f"ontology {path} is a folder; give a CSV (index,name,captions) or a JSON file")
    check_input(path, ConfigError, "give a CSV (index,name,captions) or a JSON file")
    if not os.path.isfile(path):
        raise ConfigError(f"ontology file {path} not found; give a CSV (index,name,captions) or a JSON file")
    try:
        if path.lower().endswith(".json"):
            with open(path, encoding="utf-8") as f:
                raw = json.load(f)
            if not isinstance(raw, dict):
                raise ValueError("expected an object of index -> {name, captions}")
            rows = [(k, v.get("name"), v.get("captions")) for k, v in raw.items() if isinstance(v, dict)]
            if len(rows) != len(raw):
                raise ValueError("every value must be an object with name and captions")
        else:
            with open(path, newline="", encoding="utf-8") as f:
                table = list(csv.reader(f))
            head = [c.strip().lower() for c in (table[0] if table else [])]
            if head[:3] != ["index", "name", "captions"]:
                raise ValueError("the first row must be the header index,name,captions")
            rows = []
            for n, r in enumerate(table[1:], start=2):
                if not any(c.strip() for c in r):
                    continue
                if len(r) < 3:
                    raise ValueError(f"row {n} has {len(r)} fields; expected index,name,captions")
                rows.append((r[0], r[1], [c.strip() for c in r[2].split("|")]))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, ValueError) as e:
        raise ConfigError(f"{path}: not an ontology ({e}); see docs/recorded.md") from None
    out: Ontology = {}
    for key, name, caps in rows:
        try:
            k = int(str(key).strip())
        except ValueError:
            raise ConfigError(f"{path}: class index {key!r} is not a whole number") from None
        caps = tuple(c for c in (caps or []) if isinstance(c, str) and c.strip())
        if k < 0 or not isinstance(name, str) or not name.strip() or not caps:
            raise ConfigError(f"{path}: class {key!r} needs an index >= 0, a name and at least one caption")
        if k in out:
            raise ConfigError(f"{path}: class index {k} is given twice")
        out[k] = SoundClass(k, name.strip(), caps)
    if not out:
        raise ConfigError(f"{path}: no classes; give at least one row index,name,captions")
    owner: dict[str, int] = {}
    for k, c in out.items():
        for cap in c.captions:
            if owner.setdefault(cap.strip().lower(), k) != k:
                raise ConfigError(f"{path}: the caption {cap!r} is given to classes {owner[cap.strip().lower()]} and "
                                  f"{k}; a query must name one class: word each class's captions for it alone")
    return out
