"""File formats both sides use: the codecs the exports write and the tools read back.
``coding`` (a scene's audio as ``.npy``, WAV and FLAC, bit-exact), ``webdataset`` (a
scene's tar members and the tar, ``.npy`` and sample readers), ``dcase`` (the DCASE SELD
label CSV).

Import order: ``coding``; ``webdataset`` uses it; ``dcase``.
"""
