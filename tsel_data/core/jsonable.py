"""Plain JSON data from the package's values: one conversion for configs, recipes'
bank references and shard records."""
from __future__ import annotations

import math
from dataclasses import fields, is_dataclass

import numpy as np


def jsonable(x):
    """``x`` as plain JSON data.

    Objects with a ``to_json()`` method (``Dist``, records) give its result;
    dataclasses give a dict of their fields in declaration order; tuples and arrays
    become lists, numpy scalars Python numbers, non-finite floats ``None`` (JSON has no
    NaN); dict keys keep their order.
    """
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
