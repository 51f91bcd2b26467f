"""Where work runs and how it stops: stop signals (``signals``), worker processes and the
ordered pool (``pool``), a local Dask cluster's start (``dask``), the ``Runner`` that feeds
shard tasks to any of them (``runner``), freed memory kept for reuse (``malloc``), and
stdout and stderr that may go away while a command runs (``streams``).

Import order: ``malloc``, ``signals``, ``streams``; ``pool`` uses the first two; ``dask``;
``runner`` uses ``malloc``, ``signals`` and ``pool``.
"""
