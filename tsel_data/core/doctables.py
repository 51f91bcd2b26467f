"""Tables in docs/ generated from the code (config keys, receivers): rewrite a page in place."""
from __future__ import annotations

from collections.abc import Callable


def rewrite(path: str, render: Callable[[str], str]) -> bool:
    """Replace ``path``'s text by ``render(text)``, print whether it changed, return that."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    new = render(text)
    if new != text:
        with open(path, "w", encoding="utf-8") as f:
            f.write(new)
    print(f"{path}: {'updated' if new != text else 'up to date'}")
    return new != text
