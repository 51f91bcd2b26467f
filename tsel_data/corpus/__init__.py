"""Captioned clips, the input of every dataset: the ``Clip`` record (``clip``), one reader
per manifest format (``manifests/``), the built-in synthetic corpus (``demo/``), audio I/O
and levels (``audio``), prepared clips and remembered clip checks (``prepared``,
``clipcache``), captions and their similarity (``captions``, with the sound-event
vocabulary behind it in ``lexicon``), and recorded room noise (``ambience``).

Import order: ``clip``, ``lexicon``, ``prepared``; ``audio`` uses ``prepared``,
``ambience`` and ``clipcache`` ``audio``, ``captions`` ``lexicon``; ``manifests/`` uses ``clip``, ``demo/`` ``audio``.
"""
