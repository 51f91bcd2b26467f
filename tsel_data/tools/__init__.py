"""Tools over finished datasets; they read through ``tsel_data.store`` (and the codecs of
``tsel_data.formats``) only, never the generator side, so docs/format.md is the contract
between the half that writes datasets and the half that reads them.

Scores (``evaluate``; the DCASE SELD metrics ``seld`` and ``evaluate_dcase``), label
encodings for trainers (``labels``), labels held against a classical localizer
(``verify``), summaries (``stats``), pictures and listening (``picture``, ``inspect``,
``sheet``), channel-swap augmentation with exact label transforms (``augment``), a
WebDataset export streamed back (``streaming``) and the PyTorch wrappers (``torch``).
"""
