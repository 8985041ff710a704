"""MkDocs hook (``hooks:`` in ``mkdocs.yml``): Sphinx cross-reference roles in docstrings.

The docstrings cite code as ``:class:`~.physics.simulator.Simulator``` or ``:func:`simulator```;
rendered by mkdocstrings as Markdown that reads ":class:" followed by the code. This hook drops
the role and shortens the target as Sphinx shows it (``~a.b.C`` as ``C``, ``.mod`` as ``mod``).
"""
from __future__ import annotations

import re
from typing import Any

ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|const):(<code>)([^<]*)(</code>)")


def shown(target: str) -> str:
    """The text Sphinx shows for a role's target."""
    if target.startswith("~"):
        return target.rsplit(".", 1)[-1]
    return target.lstrip(".")


def strip_roles(html: str) -> str:
    """``:role:<code>target</code>`` as ``<code>shown target</code>``."""
    return ROLE.sub(lambda m: f"{m[1]}{shown(m[2])}{m[3]}", html)


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    return strip_roles(html)
