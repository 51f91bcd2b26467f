"""The planner: a config and a corpus become scene recipes (docs/design.md, "Data flow").

The clip catalog (``catalog``: manifests read and clips checked, per split), caption
embeddings of a corpus (``embeddings``, ``tsel corpus embed``), where sources and the array
go (``placement``), the sampler (``sampler``: one recipe per scene index, a pure
function of the config, the seed and the index), and the full check of the clips a plan
draws (``drawn``: ``corpus.check = "drawn"``, scenes that drew a bad clip planned again).

Import order: ``catalog``, ``placement``; ``embeddings`` uses the catalog, ``sampler`` both,
``drawn`` the catalog and the sampler.
The renderer (``tsel_data.render``) does not import the planner.
"""
