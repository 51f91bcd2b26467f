"""The renderer: a scene recipe becomes a scene (audio, labels, record), reading nothing
but the recipe and the files it names.

``mix`` renders the spatial images of the sources (simulated rooms, banks, moving
sources), levels and the mix, decides the query and builds the record; ``noise`` renders
the diffuse noise beds a recipe asks for (spectral noise, babble, recorded ambience);
``hardware`` draws each receiver's microphones as built (``[hardware]``), which ``mix``
applies to each receiver's mixture (dsp/hardware.py).

``recorded`` cuts a scene from a real recording instead (docs/recorded.md); ``scenes``
renders any plan line by its kind.

Import order: ``noise`` and ``hardware``, then ``mix``; ``recorded``; ``scenes`` uses both.
"""
