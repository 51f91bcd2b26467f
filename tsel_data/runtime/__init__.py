"""Where work runs and how it stops: stop signals (``signals``), worker processes and the
ordered pool (``pool``), a local Dask cluster's start (``dask``), the ``Runner`` that feeds
shard tasks to any of them (``runner``), and freed memory kept for reuse (``malloc``).

Import order: ``malloc``, ``signals``; ``pool`` uses both; ``dask``; ``runner`` uses all.
"""
