"""Checks of the documentation site itself (run by `make docs-check`, after `make docs`).

1. The built site (``site/``) loads nothing from the network: no page's script, image, frame
   or stylesheet, and no stylesheet's import or font, comes from an http(s) URL (links to
   other sites are fine).
2. The strict build refuses what it should: one-page sites are built with the repository's own
   `mkdocs.yml` (inherited: the same plugins, strict mode, validation). A page whose executed
   Python block runs and whose links resolve must build; the same page with the block raising,
   with a link to a missing page, or with a link to a missing heading must fail, and the
   failure must name the problem. The working page shows that each failure comes from its
   defect, not from the set-up.

    .venv-docs/bin/python tools/docs_check.py
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# what a browser fetches by itself: src= of any element, a <link>'s href (stylesheets, icons,
# preloads), CSS url(...) and @import
REMOTE = re.compile(r"""(?:\bsrc=|<link\b[^>]*\bhref=|url\(|@import\s)\s*["']?https?://""", re.IGNORECASE)

PAGE = """# A tutorial

See [the section below](#results) and [the other page](other.md).

```python exec="on" source="above"
{code}
```

## Results
"""
WORKS = 'print("the cell ran")'

# name -> (page text, what the failed build must say)
BROKEN = {
    "a failing cell": (
        PAGE.format(code='raise RuntimeError("a deliberately broken cell")'),
        "deliberately broken cell",
    ),
    "a link to a missing page": (PAGE.format(code=WORKS).replace("other.md", "missing.md"), "missing.md"),
    "a link to a missing heading": (PAGE.format(code=WORKS).replace("#results", "#no-such-heading"), "no-such-heading"),
}


def build(workdir: Path, page: str) -> subprocess.CompletedProcess[str]:
    """Build a site of ``page`` (and a second page it links to); returns the finished mkdocs run."""
    docs = workdir / "docs"
    docs.mkdir()
    (docs / "index.md").write_text(page)
    (docs / "other.md").write_text("# Other\n")
    config = workdir / "mkdocs.yml"
    config.write_text(
        f"INHERIT: {ROOT / 'mkdocs.yml'}\n"
        f"docs_dir: {docs}\n"
        f"site_dir: {workdir / 'site'}\n"
        "nav:\n  - index.md\n  - other.md\n"
        "validation:\n  omitted_files: warn\n"
    )
    mkdocs = Path(sys.executable).with_name("mkdocs")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run(
        [str(mkdocs), "build", "--strict", "-f", str(config)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )


def remote_loads(site: Path) -> list[str]:
    """Files of the built site that make a browser fetch something from the network."""
    pages = (p for p in sorted(site.rglob("*")) if p.suffix in {".html", ".css", ".js"})
    return [str(p.relative_to(site)) for p in pages if REMOTE.search(p.read_text(errors="replace"))]


def main() -> int:
    site = ROOT / "site"
    if not (site / "index.html").is_file():
        print("docs check: no site/index.html: run make docs first", file=sys.stderr)
        return 1
    remote = remote_loads(site)
    if remote:
        print(f"docs check: pages that load from the network: {', '.join(remote[:10])}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        good = build(Path(tmp), PAGE.format(code=WORKS))
    if good.returncode != 0:
        print(f"docs check: a page with a working cell and good links did not build:\n{good.stderr}", file=sys.stderr)
        return 1
    for name, (page, says) in BROKEN.items():
        with tempfile.TemporaryDirectory() as tmp:
            bad = build(Path(tmp), page)
        if bad.returncode == 0:
            print(f"docs check: a page with {name} built without error", file=sys.stderr)
            return 1
        if says not in bad.stderr:
            print(
                f"docs check: the failed build of a page with {name} does not say {says!r}:\n{bad.stderr}",
                file=sys.stderr,
            )
            return 1
    print(
        "docs check: the site loads nothing from the network; the strict build fails on "
        + ", on ".join(BROKEN)
        + ", and builds the same page without them"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
