"""One self-contained HTML page from a report's Markdown (``flexkin reproduce``, ``flexkin
calibrate --report``): CommonMark with tables rendered by markdown-it-py, images embedded."""

from __future__ import annotations

import base64
import html
from pathlib import Path

__all__ = ["markdown_to_html"]

_CSS = """body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:70em;margin:2em auto;
padding:0 1em;line-height:1.45;color:#222}img{max-width:100%;height:auto;border:1px solid #ddd;margin:.4em 0}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}td,th{border:1px solid #ccc;padding:.2em .5em;
text-align:right}th{background:#f2f2f2}td:first-child,th:first-child{text-align:left}
pre{background:#f7f7f7;padding:.6em;overflow-x:auto;font-size:.85em}h2{border-bottom:1px solid #ddd}"""


def markdown_to_html(md: str, root: Path, title: str = "flexkin report") -> str:
    """The report's Markdown as one self-contained HTML page (CommonMark with tables, rendered by
    markdown-it-py); images under ``root`` are embedded as base64 data, links are kept.

    Parameters
    ----------
    md : str
        Markdown text.
    root : Path
        Directory the image paths are relative to.
    title : str
        Title of the page.

    Returns
    -------
    str
        The HTML document.
    """
    from markdown_it import MarkdownIt

    parser = MarkdownIt("commonmark").enable("table")
    default_image = parser.renderer.rules["image"]

    def embedded_image(tokens, idx, options, env):  # src -> data: URI of the file under root
        tok = tokens[idx]
        f = root / str(tok.attrGet("src"))
        if f.is_file():
            mime = "image/svg+xml" if f.suffix == ".svg" else f"image/{f.suffix.lstrip('.').lower()}"
            tok.attrSet("src", f"data:{mime};base64," + base64.b64encode(f.read_bytes()).decode("ascii"))
        return default_image(tokens, idx, options, env)

    parser.renderer.rules["image"] = embedded_image
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            f"<style>{_CSS}</style></head><body>\n" + parser.render(md) + "</body></html>\n")
