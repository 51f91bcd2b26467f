"""``tsel check``'s two halves, under their documented import path: the pre-flight of a
config lives in :mod:`tsel_data.preflight`, the verification of a written dataset in
:mod:`tsel_data.store.verify`."""
from .preflight import check_config
from .report import CheckReport
from .store.verify import check_dataset

__all__ = ["CheckReport", "check_config", "check_dataset"]
