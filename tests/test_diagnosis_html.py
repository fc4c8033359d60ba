"""report.html: one self-contained page (figures inline, no script, no external resource) that opens on the verdict
sentence, then the evidence: the ranking with units, where the gap is, every figure; optional keys may be absent."""

from __future__ import annotations

import base64
import json
from html.parser import HTMLParser

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from furuta_drake.diagnosis.report.files import report_json, report_markdown
from furuta_drake.diagnosis.report.html import report_html


class Page(HTMLParser):
    """The parts of a page the tests read: tags with their attributes, ids, headings and table cells."""

    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.headings: list[str] = []
        self.cells: list[str] = []
        self._open: list[str] = []
        self._text: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag in ("h1", "h2", "h3", "td", "th"):
            self._open.append(tag)
            self._text = []

    def handle_endtag(self, tag):
        if self._open and tag == self._open[-1]:
            self._open.pop()
            (self.cells if tag in ("td", "th") else self.headings).append("".join(self._text).strip())

    def handle_data(self, data):
        self._text.append(data)

    def handle_startendtag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))


def png(path, colour: str) -> bytes:
    fig = Figure(figsize=(2, 1.5), dpi=40)
    FigureCanvasAgg(fig)
    fig.add_subplot().plot([0, 1, 2], [0, 1, 0], color=colour)
    fig.savefig(path, format="png")
    return path.read_bytes()


def small_report(**extra) -> dict:
    """A hand-made report with every key of report.json, through report_json (its checks and rounding)."""
    report = {
        "verdict": "arm_coulomb_friction",
        "effects": ["arm_coulomb_friction"],
        "gap": {
            "metric": "k-step output error <RMS> & counts",
            "nominal": {"train": 2.5, "heldout": 2.6},
            "with_effects": {"train": 0.7, "heldout": 0.8},
            "heldout_reduction": 0.6923,
        },
        "ranking": [
            {
                "effect": "arm_coulomb_friction",
                "params": {"coulomb": 0.0151},
                "heldout_gap": 0.8,
                "heldout_reduction": 0.6923,
                "evidence": 0.61,
                "train_gap": 0.7,
                "at_bounds": [],
            },
            {
                "effect": "input_delay",
                "params": {"delay": 0.004},
                "heldout_gap": 2.4,
                "heldout_reduction": 0.077,
                "evidence": -0.01,
            },
        ],
        "localization": {
            "signals": {"theta": 0.25, "phi": 0.75},
            "windows": [{"log": "balance_1.csv", "start": 1.2, "end": 1.5, "why": "phi error, arm velocity reversal"}],
            "regimes": [{"regime": "arm velocity reversal", "share_of_gap": 0.8}],
            "frequency_bands": [
                {"low_hz": 0.0, "high_hz": 1.0, "share_of_gap": 0.3},
                {"low_hz": 1.0, "high_hz": 3.0, "share_of_gap": 0.7},
            ],
        },
        **extra,
    }
    return json.loads(report_json(report))


@pytest.fixture
def figures(tmp_path):
    images = {
        "residuals.png": ("Prediction residuals over time", png(tmp_path / "residuals.png", "C0")),
        "effect_arm_coulomb_friction.png": (
            "Fitted arm friction",
            png(tmp_path / "effect_arm_coulomb_friction.png", "C1"),
        ),
    }
    return {name: caption for name, (caption, _) in images.items()}, {n: b for n, (_, b) in images.items()}


def test_the_page_is_self_contained_with_the_verdict_first_and_every_figure_inline(tmp_path, figures):
    captions, images = figures
    page = Page(report_html(small_report(), tmp_path, captions))
    # 0.0151 N m is 15 mN m; 1 - 0.8 / 2.6 of the held-out gap is 69 %
    assert page.headings[0].startswith("The arm's sliding (Coulomb) friction is about 15 mN m; this removes 69 %")
    assert [tag for tag, _ in page.tags].count("h1") == 1
    inlined = [attrs["src"] for tag, attrs in page.tags if tag == "img"]
    assert [base64.b64decode(src.split(",", 1)[1]) for src in inlined] == list(images.values())
    assert all(src.startswith("data:image/png;base64,") for src in inlined)
    alts = [attrs["alt"] for tag, attrs in page.tags if tag == "img"]
    assert alts == list(captions.values())
    assert [tag for tag, _ in page.tags].count("svg") == 2  # the before/after and localisation charts, inline
    ids = {attrs["id"] for _, attrs in page.tags if "id" in attrs}
    for tag, attrs in page.tags:
        assert tag not in ("script", "link", "iframe", "object", "embed", "base"), tag
        for key in ("src", "href"):
            if key in attrs:
                value = attrs[key]
                assert value.startswith("data:") or (value.startswith("#") and value[1:] in ids), value


def test_the_ranking_has_units_and_percentages_and_the_evidence_follows_the_answer(tmp_path, figures):
    page = Page(report_html(small_report(), tmp_path, figures[0]))
    assert "coulomb = 15.1 mN m" in page.cells and "69.2 %" in page.cells and "delay = 4 ms" in page.cells
    order = [
        "The accepted effects",
        "The evidence",
        "Candidates tried",
        "Where the gap is",
        "More figures",
    ]
    assert [h for h in page.headings if h in order] == order
    assert "phi error, arm velocity reversal" in page.cells and "1.2-1.5 s" in page.cells
    text = report_html(small_report(), tmp_path, {})
    assert "k-step output error &lt;RMS&gt; &amp; counts" in text  # the metric, folded with the rule


def test_optional_keys_are_shown_when_present(tmp_path):
    report = small_report(
        uncertainty="bootstrap over windows",
        steps=[{"effect": "arm_coulomb_friction", "heldout_gap": 0.8, "heldout_reduction": 0.6923}],
    )
    report["ranking"][0]["params_ci"] = {"coulomb": [0.0142, 0.0160]}
    report["ranking"][1].update(status="failed", reason="the fit diverged")
    report["localization"]["after"] = {
        "signals": {"theta": 0.5, "phi": 0.5},
        "regimes": [{"regime": "arm velocity reversal", "share_of_gap": 0.1}],
        "frequency_bands": [{"low_hz": 0.0, "high_hz": 1.0, "share_of_gap": 0.2}],
    }
    text = report_html(report, tmp_path, {})
    page = Page(text)
    assert "coulomb = 15.1 mN m [14.2 mN m to 16 mN m]" in page.cells
    assert "input_delay: the fit diverged" in text
    assert "One row per accepted step" in page.headings
    assert "<b>Intervals.</b> bootstrap over windows." in text
    assert "with the accepted effects" in text[text.index('id="localization"') :]  # the after bars' legend


def test_a_screened_candidate_is_listed_apart_from_the_fitted_ones(tmp_path):
    """A candidate its step's screen left behind has a screen's values, not a fit's: the page and report.md list it
    with the reason, outside the table of fitted candidates."""
    report = small_report()
    reason = "its screen reduced the nominal gap on the start windows by 4 %, the best screen by 90 %: not fitted"
    report["ranking"][1].update(status="screened", reason=reason)
    text = report_html(report, tmp_path, {})
    assert "delay = 4 ms" not in Page(text).cells and "coulomb = 15.1 mN m" in Page(text).cells
    assert "1 candidates screened out" in text and f"input_delay: {reason}" in text
    markdown = report_markdown(report, {})
    assert f"Screened out (not fitted further):\n\n- input_delay: {reason}" in markdown
    assert "delay = 4 ms" not in markdown


def test_a_report_with_only_the_required_keys_renders(tmp_path):
    report = small_report()
    report["localization"].update(windows=[], regimes=[], frequency_bands=[])
    page = Page(report_html(report, tmp_path, {}))
    assert page.headings[0].startswith("The arm's sliding (Coulomb) friction")
    assert "The worst time windows (rig file)" not in report_html(report, tmp_path, {})
