"""The package version (its own module, so any layer can read it without importing the package root)."""
__version__ = "0.2.0"


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
