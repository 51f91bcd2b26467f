"""Progress bars for long work: one look for every command (a tqdm bar on stderr with a
count, a rate and the time left, as ``tsel generate``'s)."""
from __future__ import annotations

import sys

from tqdm import tqdm


def bar(total: int | None, desc: str, unit: str, show: bool | None = True, initial: int = 0) -> tqdm:
    """A progress bar on stderr.

    Parameters
    ----------
    total : int or None
        Units of work (None: a counter without a percentage).
    desc : str
        What is being done, e.g. ``check train`` (left of the bar).
    unit : str
        What a unit is (``clip``, ``scene``, ``room``): the rate reads ``12.3clip/s``.
    show : bool or None
        True: always; False: never; None: only when stderr is a terminal (work that
        also runs inside ``tsel check`` and scripts, whose stderr is their messages).
    initial : int
        Units already done (a resumed job).
    """
    if show is None:
        show = on_terminal()
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, disable=not show, dynamic_ncols=True,
                mininterval=0.5, file=sys.stderr)


def on_terminal() -> bool:
    """Whether stderr is a terminal (a person watching, not a log file)."""
    return sys.stderr.isatty()
