"""tsel-data: datasets for text-queried target sound event localization."""

__version__ = "0.1.0"
