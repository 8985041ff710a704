"""The CLI reference page, generated from the ``microconveyor`` argparse parsers.

Every registered command is included, the agents' (``microconveyor_env.commands`` entry points)
too: the page is built from :func:`microconveyor_env.cli.build_parser`, so it cannot drift from
``microconveyor COMMAND --help``.

Two uses:

* an MkDocs hook (``hooks:`` in ``mkdocs.yml``): the page ``cli-reference.md`` is added to the
  site at build time, no file written into ``docs/``;
* a script: ``python3 scripts/gen_cli_reference.py [OUT.md]`` prints the page (or writes it).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

PAGE = "cli-reference.md"
WIDTH = 80  # help text wrapped at a fixed width (the site's code column), whatever the terminal


def _fixed_width(parser: argparse.ArgumentParser) -> None:
    def formatter(prog: str) -> argparse.HelpFormatter:
        return argparse.HelpFormatter(prog, width=WIDTH)

    parser.formatter_class = formatter


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    raise RuntimeError("the microconveyor parser has no subcommands")


def reference() -> str:
    """The page: ``microconveyor --help``, then each command's ``--help``, by name."""
    from microconveyor_env.cli import build_parser

    parser = build_parser()
    commands = _subparsers(parser)
    for p in [parser, *commands.values()]:
        _fixed_width(p)
    out = [
        "# CLI reference",
        "",
        "Generated from the `microconveyor` argument parsers at build time: each section is what",
        "`microconveyor COMMAND --help` prints. The error and `--json` contract, and examples of",
        "each command, are in [The command line](cli.md).",
        "",
        "```text",
        parser.format_help().rstrip(),
        "```",
        "",
        "Commands: " + ", ".join(f"[`{n}`](#{_anchor(n)})" for n in sorted(commands)) + ".",
        "",
    ]
    for name in sorted(commands):
        out += [f"## {name}", "", "```text", commands[name].format_help().rstrip(), "```", ""]
    return "\n".join(out)


def _anchor(name: str) -> str:
    """The heading id MkDocs (Python-Markdown's toc) gives ``## name``."""
    return name.lower().replace(" ", "-")


def on_files(files: Any, config: Any) -> Any:
    """MkDocs hook: add the generated page to the site."""
    from mkdocs.structure.files import File

    files.append(File.generated(config, PAGE, content=reference()))
    return files


def main(argv: list[str]) -> int:
    text = reference()
    if argv:
        Path(argv[0]).write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
