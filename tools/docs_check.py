"""Checks of the documentation site itself (run by `make docs-check`, after `make docs`).

1. The built site (``site/``) loads nothing from the network: no page's script, image, frame
   or stylesheet, and no stylesheet's import or font, comes from an http(s) URL (links to
   other sites are fine).
2. A failing tutorial cell fails the build: two one-page sites are built with the repository's
   own `mkdocs.yml` (inherited: the same plugins, strict mode, validation), each page holding
   one executed Python block; the one that runs must build, the one that raises must fail the
   build and name the error. The pair shows that the failure comes from the cell, not from the
   set-up.

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

CELL = """# A tutorial

```python exec="on" source="above"
{code}
```
"""


def build(workdir: Path, code: str) -> subprocess.CompletedProcess[str]:
    """Build a one-page site whose page executes ``code``; returns the finished mkdocs process."""
    docs = workdir / "docs"
    docs.mkdir()
    (docs / "index.md").write_text(CELL.format(code=code))
    config = workdir / "mkdocs.yml"
    config.write_text(
        f"INHERIT: {ROOT / 'mkdocs.yml'}\n"
        f"docs_dir: {docs}\n"
        f"site_dir: {workdir / 'site'}\n"
        "nav:\n  - index.md\n"
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
    with tempfile.TemporaryDirectory() as good_dir, tempfile.TemporaryDirectory() as bad_dir:
        good = build(Path(good_dir), 'print("the cell ran")')
        if good.returncode != 0:
            print(f"docs check: a page with a working cell did not build:\n{good.stderr}", file=sys.stderr)
            return 1
        bad = build(Path(bad_dir), 'raise RuntimeError("a deliberately broken cell")')
        if bad.returncode == 0:
            print("docs check: a page with a failing cell built without error", file=sys.stderr)
            return 1
        if "a deliberately broken cell" not in bad.stderr:
            print(f"docs check: the failed build does not name the cell's error:\n{bad.stderr}", file=sys.stderr)
            return 1
    print(
        "docs check: the site loads nothing from the network; a working cell builds, a failing one fails "
        "the strict build and is named"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
