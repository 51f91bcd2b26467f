"""The package version (its own module, so any layer can read it without importing the package root)."""
__version__ = "0.3.0"

# The renderer: what a scene's bytes depend on besides its recipe and its clips. Raised,
# deliberately, when a faster or better path cannot give the same bytes; dataset.json and
# recipe releases record it (a document without it: renderer 1), and a rebuild by another
# renderer names the tsel-data version that made the release, which rebuilds it bit for bit.
#   1: up to 0.2.0
#   2: 0.3.0: moving simulated sources' knots at once, their DC blocker after the
#      render, arcs' knots every 4.5 cm (issue 43); rigid spheres' images as point sources
#      and interpolated binaural HRIRs blended time-aligned (issue 40); other static
#      scenes and bank walks as renderer 1
RENDERER = 2


def renderer_of(doc: dict) -> int:
    """The renderer a dataset.json or release.json was made by."""
    value = doc.get("renderer", 1)
    return value if isinstance(value, int) and not isinstance(value, bool) else 1


def is_newer(version) -> bool:
    """Whether ``version`` (a document's "version", e.g. "0.3.1") is a later tsel-data
    than this one: what it wrote may hold keys this one does not know."""
    def parts(v):
        out = []
        for p in str(v).split("."):
            digits = "".join(c for c in p if c.isdigit()) if p[:1].isdigit() else ""
            if not digits:
                break
            out.append(int(digits))
        return tuple(out)

    return parts(version) > parts(__version__)
