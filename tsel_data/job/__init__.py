"""Jobs over whole datasets: plan -> render shards -> finalize (``pipeline``; a plan read
back, its shards rendered and finalized in ``shards``), the same scenes rendered on demand
for trainers (``onthefly``), one stored scene's sources rendered again alone (``stems``,
``tsel inspect --wav``), a recipe release rebuilt and held against its checksums
(``rebuild``, ``tsel generate --from``), and every problem of a config collected before any
work (``preflight``, ``tsel check CONFIG``).

Import order: ``shards``; ``pipeline`` and ``stems`` use it; ``rebuild`` and ``preflight`` use
``pipeline``; ``onthefly`` uses none of them.
"""
