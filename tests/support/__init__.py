"""Helpers the tests share: plane-wave datasets written through the real writer
(``datasets``), RIR banks, HRTF and ambience files in the layouts people have
(``banks``, ``hrtf``, ``ambience``), the small configs of generated datasets
(``configs``) and the command line run in process (``cli``)."""
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
