"""Support every stage uses, with no knowledge of scenes: the coordinate conventions and
geometry (``geometry``: ``Room``, ``SOUND_SPEED``, angles, label interpolation), plain-JSON
and HDF5-text helpers (``jsonable``, ``h5str``), atomic writes (``atomic``), a file's sha256
(``digest``), what a path is before it is opened and names read from files kept inside
their folder (``files``), the progress bar (``progress``), check reports (``report``), the tables docs/
generate from the code (``doctables``), the C library's few calls ``os`` lacks (``libc``),
scipy's compiled loops loaded without their subpackages (``compiled``), the version.

Import order: none imports another but ``atomic`` (``jsonable``, ``libc``); ``atomic``,
``files`` and ``report`` import ``tsel_data.errors``.
"""
