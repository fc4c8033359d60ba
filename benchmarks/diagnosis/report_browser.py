"""Open diagnosis reports offline in headless Chromium at 1280 px and check what a reader sees (not a test: CI has
no browser).

For each report directory given (or built, ``--fake-logs N``: a report.json whose held-out figures have N logs'
rows, rendered with the figures of the first directory), the script

- renders ``report.html`` again from ``report.json`` with the current code (``--as-written`` keeps the file);
- checks the page is self-contained: no ``http://`` or ``https://`` anywhere, no script, no external resource;
- measures its size (target: under 3 MB, also for a 200-log diagnosis);
- opens a copy in headless Chromium (``--headless --dump-dom`` with a measuring script appended to the copy only)
  at 1280 x 800 and reads: every ``<img>``'s naturalWidth > 0 and every ``<svg>``'s drawn width > 0; the
  document's scrollWidth <= 1280; the bottom of the verdict sentence, of the before/after chart and of the first
  next step within the first 800 px;
- saves screenshots of the first screen and of the whole page (``OUT/<name>_first.png``, ``OUT/<name>_full.png``).

Prints one row per report with each check and exits 1 when one fails. Run from the repository root:
``PYTHONPATH=. python benchmarks/diagnosis/report_browser.py DIAGNOSIS_DIR [MORE_DIRS ...] --out shots --fake-logs 200``
"""

from __future__ import annotations

import argparse
import copy
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from furuta_drake.diagnosis.report.files import report_json
from furuta_drake.diagnosis.report.html import report_html

WIDTH, FIRST_SCREEN = 1280, 800
MAX_BYTES = 3_000_000
EXTERNAL = re.compile(r"https?://|<script|<link|<iframe|<object|<embed", re.I)
MEASURE = """<script>
const box = (selector) => { const e = document.querySelector(selector); return e ? e.getBoundingClientRect() : null; };
const images = [...document.images].map((i) => i.naturalWidth);
const svgs = [...document.querySelectorAll('svg')].map((s) => s.getBoundingClientRect().width);
const bottom = (selector) => { const b = box(selector); return b ? b.bottom : null; };
document.body.setAttribute('data-measure', JSON.stringify({
  scrollWidth: document.documentElement.scrollWidth, scrollHeight: document.documentElement.scrollHeight,
  images, svgs, verdict: bottom('#verdict'), picture: bottom('.picture svg'), next: bottom('ol.next li'),
}));
</script>"""


def chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return name
    sys.exit("no Chromium found: apt-get install chromium")


def browse(page: Path, *args: str, height: int = FIRST_SCREEN) -> str:
    command = [
        chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--allow-file-access-from-files",
        f"--window-size={WIDTH},{height}",
        *args,
        page.as_uri(),
    ]
    return subprocess.run(command, capture_output=True, text=True, timeout=120, check=True).stdout


def measure(page_text: str, work: Path) -> dict:
    probe = work / "probe.html"
    probe.write_text(page_text.replace("</body>", MEASURE + "</body>"))
    dom = browse(probe, "--dump-dom", "--virtual-time-budget=3000")
    found = re.search(r"data-measure=\"([^\"]*)\"", dom)
    return json.loads(found.group(1).replace("&quot;", '"')) if found else {}


def figures_of(directory: Path) -> dict[str, str]:
    """The evidence figures a report directory holds, with report.md's captions, in write_report's order."""
    linked = dict(re.findall(r"!\[([^\]]*)\]\(([^)]+)\)", (directory / "report.md").read_text()))
    captions = {name: caption for caption, name in linked.items()}
    names = [n for n in ("windows.svg", "residuals.png", "residual_spectra.png") if (directory / n).exists()]
    names += sorted(p.name for p in directory.glob("effect_*.png"))
    return {name: captions.get(name, Path(name).stem) for name in names}


def check(name: str, report: dict, directory: Path, out: Path, as_written: bool) -> dict:
    page_path = directory / "report.html"
    text = page_path.read_text() if as_written else report_html(report, directory, figures_of(directory))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        found = measure(text, work)
        page = work / "report.html"
        page.write_text(text)
        browse(page, f"--screenshot={out / f'{name}_first.png'}")
        height = min(int(found.get("scrollHeight", FIRST_SCREEN)), 16000)
        browse(page, f"--screenshot={out / f'{name}_full.png'}", height=height)
    in_first = [found.get(key) for key in ("verdict", "picture", "next")]
    return {
        "report": name,
        "bytes": len(text.encode()),
        "self_contained": not EXTERNAL.search(text),
        "images_render": all(w > 0 for w in found.get("images", [0])) if found.get("images") else True,
        "svgs_render": bool(found.get("svgs")) and all(w > 0 for w in found["svgs"]),
        "figures": f"{len(found.get('images', []))} img, {len(found.get('svgs', []))} svg",
        "scroll_width": found.get("scrollWidth"),
        "first_screen": all(b is not None and b <= FIRST_SCREEN for b in in_first),
        "bottoms_px": "/".join("-" if b is None else f"{b:.0f}" for b in in_first),
    }


def fake_logs(report: dict, logs: int) -> dict:
    """The report with ``logs`` held-out logs' rows (per-log errors and worst windows), for the size check."""
    fake = copy.deepcopy(report)
    rows = fake["gap"].get("heldout_rms_per_log") or [
        {"log": "run.csv", "nominal": {"theta": 1.0, "phi": 1.2}, "with_effects": {"theta": 0.3, "phi": 0.4}}
    ]
    fake["gap"]["heldout_rms_per_log"] = [
        {
            **rows[i % len(rows)],
            "log": f"run_{i:03d}.csv",
            "nominal": {k: v * (1 + i % 7 / 10) for k, v in rows[i % len(rows)]["nominal"].items()},
        }
        for i in range(logs)
    ]
    return json.loads(report_json(fake))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reports", nargs="+", type=Path, help="report directories (each with report.json)")
    parser.add_argument("--out", type=Path, required=True, help="directory for the screenshots")
    parser.add_argument("--fake-logs", type=int, default=0, help="also check a report of this many held-out logs")
    parser.add_argument("--as-written", action="store_true", help="check report.html as written, not re-rendered")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for directory in args.reports:
        report = json.loads((directory / "report.json").read_text())
        rows.append(check(directory.name, report, directory, args.out, args.as_written))
    if args.fake_logs:
        first = args.reports[0]
        fake = fake_logs(json.loads((first / "report.json").read_text()), args.fake_logs)
        rows.append(check(f"fake_{args.fake_logs}_logs", fake, first, args.out, False))
    keys = list(rows[0])
    print(" | ".join(keys))
    for row in rows:
        print(" | ".join(str(row[k]) for k in keys))
    failed = [
        row["report"]
        for row in rows
        if not (row["self_contained"] and row["images_render"] and row["svgs_render"] and row["first_screen"])
        or (row["scroll_width"] or WIDTH + 1) > WIDTH
        or row["bytes"] >= MAX_BYTES
    ]
    print("all checks pass" if not failed else f"failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
