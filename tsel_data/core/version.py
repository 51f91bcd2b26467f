"""The package version (its own module, so any layer can read it without importing the package root)."""
__version__ = "0.2.0"

# The renderer: what a scene's bytes depend on besides its recipe and its clips. Raised,
# deliberately, when a faster or better path cannot give the same bytes; dataset.json and
# recipe releases record it (a document without it: renderer 1), and a rebuild by another
# renderer names the tsel-data version that made the release, which rebuilds it bit for bit.
#   1: up to 0.2.0
#   2: moving simulated sources' knots at once, their DC blocker after the render, arcs'
#      knots every 4.5 cm (issue 43); static scenes and bank walks as renderer 1
RENDERER = 2


def renderer_of(doc: dict) -> int:
    """The renderer a dataset.json or release.json was made by."""
    value = doc.get("renderer", 1)
    return value if isinstance(value, int) and not isinstance(value, bool) else 1
