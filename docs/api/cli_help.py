"""mkdocs hook: replaces `<!-- rockjax-help COMMAND -->` in a page with the text of
`rockjax COMMAND --help`, taken from the command line's own parser, so that the CLI page
of the API reference never drifts from the code (`<!-- rockjax-help -->`: `rockjax --help`)."""

from __future__ import annotations

import os
import re
import sys

MARKER = re.compile(r"<!-- rockjax-help ?([a-z_-]*) -->")


def _help(command: str) -> str:
    import contextlib
    import io

    from rockjax.cli import build_parser

    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal's width
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
        build_parser().parse_args([command, "--help"] if command else ["--help"])
    text = out.getvalue()
    if not text.strip():
        raise ValueError(f"no help text for rockjax {command}")
    return text


def on_config(config):
    # the source tree's rockjax, as the API pages (mkdocstrings' `paths: [.]`)
    root = os.path.dirname(os.path.abspath(config.config_file_path))
    if root not in sys.path:
        sys.path.insert(0, root)
    return config


def on_page_markdown(markdown, page, config, files):
    return MARKER.sub(lambda m: f"```text\n{_help(m.group(1)).rstrip()}\n```", markdown)
