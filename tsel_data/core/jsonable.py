"""Plain JSON data from the package's values: one conversion for configs, recipes'
bank references and shard records."""
from __future__ import annotations

import math
from dataclasses import MISSING, field, fields, is_dataclass

import numpy as np


def jsonable(x):
    """``x`` as plain JSON data.

    Objects with a ``to_json()`` method (``Dist``, records) give its result;
    dataclasses give a dict of their fields in declaration order; tuples and arrays
    become lists, numpy scalars Python numbers, non-finite floats ``None`` (JSON has no
    NaN); dict keys keep their order.
    """
    t = type(x)  # plain values first: a scene's record is mostly lists of label numbers
    if t is float:
        return x if math.isfinite(x) else None
    if t is str or t is int or t is bool or x is None:
        return x
    if t is list:
        return [jsonable(v) for v in x]
    if hasattr(x, "to_json"):
        return jsonable(x.to_json())
    if is_dataclass(x) and not isinstance(x, type):
        return {f.name: jsonable(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


# --- records and recipes whose JSON is their fields ---------------------------------------------

_CODEC = "json"
_NONE = object()


def key(default=MISSING, *, default_factory=MISSING, omit=None, encode=None, decode=None, missing=_NONE):
    """A dataclass field as one key of the class's JSON (:class:`JsonFields`): ``omit(obj)``
    True leaves the key out (an optional key, declared here once); ``encode(value)`` and
    ``decode(json value)`` convert it; ``missing``: the value when the JSON lacks the key
    (default: the field's default)."""
    meta = {_CODEC: (omit, encode, decode, missing)}
    if default_factory is not MISSING:
        return field(default_factory=default_factory, metadata=meta)
    return field(default=default, metadata=meta)


def unset(name: str):
    """``omit`` of a key written only when its field is set: a later addition, so what was
    written without it keeps its bytes."""
    return lambda obj: getattr(obj, name) is None


def rows(v) -> list:
    return [list(x) for x in v]


class JsonFields:
    """``to_json``/``from_json`` derived from a dataclass's fields: key order is field
    order, a field declared with :func:`key` may be optional or converted. Subclasses are
    dataclasses; their JSON form is a contract (docs/format.md), so the order of their
    fields is too."""

    _codecs: dict = {}

    @classmethod
    def _codec(cls) -> list:
        found = JsonFields._codecs.get(cls)
        if found is None:
            found = JsonFields._codecs[cls] = [(f.name, *f.metadata.get(_CODEC, (None, None, None, _NONE)),
                                                json_types(f.type, f.metadata.get(_CODEC, (0, 0, None))[2] is not None))
                                               for f in fields(cls)]
        return found

    def to_json(self) -> dict:
        out = {}
        for name, omit, encode, _, _, _ in self._codec():
            if omit is not None and omit(self):
                continue
            value = getattr(self, name)
            out[name] = encode(value) if encode is not None else value
        return out

    @classmethod
    def from_json(cls, d: dict | None):
        """The object of the JSON form ``d``; ValueError naming the key when ``d`` is not an
        object or a key holds another JSON type than its field's (a string for a list:
        a file damaged or written by hand), so nothing of the wrong shape is built."""
        d = d or {}
        if not isinstance(d, dict):
            raise ValueError(f"expected a JSON object, got {_json_name(d)}")
        kw = {}
        for name, _, _, decode, missing, types in cls._codec():
            if name in d:
                value = d[name]
                if types is not None and (not isinstance(value, types) or isinstance(value, bool) and bool not in types):
                    raise ValueError(f"key {name!r} holds {_json_name(value)}, not {_names(types)}")
                kw[name] = decode(value) if decode is not None else value
            elif missing is not _NONE:
                kw[name] = missing
            elif name in _required(cls):
                raise ValueError(f"no key {name!r}")
        return cls(**kw)

    # recipes' names for the same pair (a recipe's ``to_json`` is its JSON line)
    def to_dict(self) -> dict:
        return self.to_json()

    @classmethod
    def from_dict(cls, d: dict | None):
        return cls.from_json(d)


def _required(cls) -> set:
    """The fields of ``cls`` without a default: keys its JSON must have."""
    found = _REQUIRED.get(cls)
    if found is None:
        found = _REQUIRED[cls] = {f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING}
    return found


_REQUIRED: dict = {}
# the JSON types of a field's annotation (written as text: ``from __future__ import annotations``)
_JSON_TYPES = {"str": (str,), "int": (int,), "float": (int, float), "bool": (bool,), "list": (list,),
               "tuple": (list,), "dict": (dict,), "None": (type(None),)}


def json_types(annotation, decoded: bool = False) -> tuple | None:
    """The JSON types a field of ``annotation`` may hold (``"float | None"`` -> int, float,
    None), or None when it names a class of its own (its decoder checks it). A field
    with a decoder may also be null (decoders read null as empty)."""
    out: tuple = ()
    for part in str(annotation).split("|"):
        part = part.strip().split("[", 1)[0]
        if part not in _JSON_TYPES:
            return None
        out += _JSON_TYPES[part]
    if decoded:
        out += (type(None),)
    return tuple(dict.fromkeys(out))


def _json_name(value) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(value), "a number" if isinstance(value, (int, float)) else type(value).__name__)


def _names(types: tuple) -> str:
    names = dict.fromkeys({dict: "an object", list: "a list", str: "a string", bool: "a boolean", int: "a number",
                           float: "a number", type(None): "null"}[t] for t in types)
    return " or ".join(names)
