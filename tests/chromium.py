"""Open a page in headless Chromium (Debian package chromium): a screenshot, the console,
and how many of its images decoded (a probe script added to a copy of the page)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr",
         "--v=0", "--window-size=1000,1600"]
PROBE = ("<script>document.body.setAttribute('data-broken', String(Array.from("
         "document.images).filter(i => !(i.complete && i.naturalWidth > 0)).length));"
         "document.body.setAttribute('data-images', String(document.images.length));"
         "</script></body>")


def open_page(page: Path, tmp_path: Path) -> dict:
    """Screenshot size [bytes], console stderr, image count, broken images and the DOM."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("chromium (Debian package chromium) is not installed")
    shot = tmp_path / "shot.png"
    run = subprocess.run([browser, *FLAGS, f"--screenshot={shot}", page.as_uri()],
                         capture_output=True, text=True, timeout=120, check=False)
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text().replace("</body>", PROBE))
    dom = subprocess.run([browser, *FLAGS, "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120, check=False).stdout
    images = re.search(r'data-images="(\d+)"', dom)
    broken = re.search(r'data-broken="(\d+)"', dom)
    return {"screenshot_bytes": shot.stat().st_size if shot.exists() else 0,
            "stderr": run.stderr, "dom": dom,
            "images": int(images.group(1)) if images else -1,
            "broken": int(broken.group(1)) if broken else -1}
