"""The report's charts as SVG text: the held-out error before and after the effects per log and signal, the
detection limits, where the gap is, and measured against nominal against corrected predictions on held-out windows.

Every chart but the last reads only a ``report.json`` object, so an old report's page still gets them; the last
reads the residual windows (:class:`~furuta_drake.diagnosis.logs.load.WindowResiduals`). The SVG keeps its text as
text and its element ids seeded, so the same report gives the same bytes; it is inlined in ``report.html`` and
written beside ``report.md``.
"""

from __future__ import annotations

import io
import math

import matplotlib
import numpy as np
from matplotlib.backends.backend_svg import FigureCanvasSVG
from matplotlib.figure import Figure

from furuta_drake.diagnosis.formatting import number, scale_of
from furuta_drake.diagnosis.gap.localize import SENSOR_VARIANCE
from furuta_drake.diagnosis.logs.load import WindowResiduals

NOMINAL, CORRECTED, MEASURED = "#9a9a9a", "#1f6fb4", "#111111"
SIGNALS = ("theta", "phi")
MAX_BAR_LOGS = 10  # more held-out logs than this are drawn as a scatter of error with against without the effects
TYPICAL_WINDOWS = 2  # windows of median error shown beside the worst one


def svg(fig: Figure) -> str:
    """The figure as an ``<svg>`` element (no XML prologue), text as text, ids seeded by the content."""
    buffer = io.StringIO()
    FigureCanvasSVG(fig)
    if not fig.legends:
        fig.tight_layout()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "furuta-drake"}):
        fig.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
    text = buffer.getvalue()
    return text[text.index("<svg") :]


def _hbars(ax, labels: list[str], before: list, after: list | None, unit: str) -> None:
    y = np.arange(len(labels))
    height = 0.4 if after is not None else 0.7
    ax.barh(y - (height / 2 if after is not None else 0), _finite(before), height, color=NOMINAL, label="rig file")
    if after is not None:
        ax.barh(y + height / 2, _finite(after), height, color=CORRECTED, label="with the accepted effects")
    ax.set_yticks(y, labels, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel(unit, fontsize=8)
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", alpha=0.3)


def _legend(fig: Figure, ax) -> None:
    """The legend above the axes, clear of the bars."""
    fig.legend(*ax.get_legend_handles_labels(), loc="upper center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / fig.get_figheight()))


def _finite(values) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], float)


def gap_chart(report: dict) -> Figure:
    """Held-out RMS prediction error [counts] per log and signal, rig file against the accepted effects; the
    whole held-out gap when the report has no per-log rows."""
    gap = report["gap"]
    rows = gap.get("heldout_rms_per_log") or []
    after_known = bool(report.get("effects"))
    if len(rows) > MAX_BAR_LOGS:
        return _gap_scatter(rows)
    if rows:
        labels = [f"{row['log']} · {s}" for row in rows for s in SIGNALS]
        before = [row["nominal"][s] for row in rows for s in SIGNALS]
        after = [row["with_effects"][s] for row in rows for s in SIGNALS] if after_known else None
        unit = "held-out RMS prediction error [counts]"
    else:
        labels = ["all held-out logs"]
        before, after = [gap["nominal"]["heldout"]], [gap["with_effects"]["heldout"]] if after_known else None
        unit = "held-out gap [counts]"
    fig = Figure(figsize=(6.4, 0.85 + 0.32 * len(labels) * (2 if after else 1)))
    ax = fig.subplots()
    _hbars(ax, labels, before, after, unit)
    if rows:  # an RMS error at this line is the encoder's rounding alone
        ax.axvline(math.sqrt(SENSOR_VARIANCE), color=MEASURED, ls=":", lw=1.2, label="encoder rounding alone")
    top = float(np.nanmax(np.append(_finite(before + (after or [])), math.sqrt(SENSOR_VARIANCE) if rows else 0.0)))
    ax.set_xlim(0, 1.05 * top if top > 0 else 1.0)
    _legend(fig, ax)
    return fig


def _gap_scatter(rows: list[dict]) -> Figure:
    fig = Figure(figsize=(6.4, 3.2))
    ax = fig.subplots()
    top = 0.0
    for signal, marker in zip(SIGNALS, ("o", "s")):
        x = _finite([row["nominal"][signal] for row in rows])
        y = _finite([row["with_effects"][signal] for row in rows])
        ax.scatter(x, y, s=12, marker=marker, alpha=0.7, label=signal)
        top = max(top, np.nanmax(x), np.nanmax(y))
    ax.plot([0, top], [0, top], color=NOMINAL, lw=1, label="no change")
    ax.set_xlabel("rig file [counts RMS]", fontsize=8)
    ax.set_ylabel("with the accepted effects [counts RMS]", fontsize=8)
    ax.set_title(f"Held-out prediction error of {len(rows)} logs (below the line: better)", fontsize=9)
    ax.legend(fontsize=8, frameon=False)
    ax.grid(alpha=0.3)
    return fig


def limits_chart(limits: list[dict]) -> Figure | None:
    """One panel per unit: the smallest size of each effect not accepted that these logs would have detected
    (gains and scales as their distance from 1 in %)."""
    groups: dict[tuple[str, str], list[tuple[str, float | None]]] = {}
    for limit in limits:
        value, unit = limit["value"], limit["unit"]
        if unit == "-":
            value, unit = (None if value is None else 100 * abs(value - 1)), "% from 1"
        what = "largest limit detected" if limit["param"] == "limit" else "smallest size detected"
        groups.setdefault((unit, what), []).append((limit["effect"], value))
    if not groups:
        return None
    heights = [len(rows) + 1.6 for rows in groups.values()]
    fig = Figure(figsize=(6.4, 0.28 * sum(heights) + 0.3))
    axes = fig.subplots(len(groups), 1, squeeze=False, gridspec_kw={"height_ratios": heights})[:, 0]
    for ax, ((unit, what), rows) in zip(axes, groups.items()):
        known = [v for _, v in rows if v is not None]
        factor, shown = scale_of(max(known), unit) if known else (1.0, unit)
        values = [None if v is None else v / factor for _, v in rows]
        _hbars(ax, [name for name, _ in rows], values, None, f"{what} [{shown}]")
        for i, value in enumerate(values):
            ax.annotate(
                "not detected at any size" if value is None else f" {number(value, 2)}",
                (0 if value is None else value, i),
                va="center",
                fontsize=7,
            )
        ax.set_xlim(0, 1.25 * max(known) / factor if known else 1)
    return fig


def localization_chart(localization: dict) -> Figure | None:
    """Shares of the gap by signal, by regime (next to the regime's share of the samples) and by band, with the
    rig file and with the accepted effects."""
    if not localization.get("signals"):
        return None
    after = localization.get("after") or {}
    fig = Figure(figsize=(10, 2.9))
    axes = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1, 2.2, 1.6]})
    signals = list(localization["signals"])
    _hbars(
        axes[0],
        signals,
        [100 * (localization["signals"][s] or 0) for s in signals],
        [100 * (after.get("signals", {}).get(s) or 0) for s in signals] if after else None,
        "share of the gap [%]",
    )
    regimes = localization.get("regimes", [])
    after_regimes = {r["regime"]: r["share_of_gap"] for r in after.get("regimes", [])}
    _hbars(
        axes[1],
        [r["regime"] for r in regimes],
        [100 * (r["share_of_gap"] or 0) for r in regimes],
        [100 * (after_regimes.get(r["regime"]) or 0) for r in regimes] if after else None,
        "share of the gap [%] (| share of the samples)",
    )
    for i, r in enumerate(regimes):
        if r.get("share_of_samples") is not None:
            axes[1].plot([100 * r["share_of_samples"]] * 2, [i - 0.45, i + 0.45], color=MEASURED, lw=1.5)
    bands = localization.get("frequency_bands", [])
    after_bands = {(b["low_hz"], b["high_hz"]): b["share_of_gap"] for b in after.get("frequency_bands", [])}
    _hbars(
        axes[2],
        [f"{b['low_hz']:g}-{b['high_hz']:g} Hz" for b in bands],
        [100 * (b["share_of_gap"] or 0) for b in bands],
        [100 * (after_bands.get((b["low_hz"], b["high_hz"])) or 0) for b in bands] if after else None,
        "share of the gap [%]",
    )
    _legend(fig, axes[0])
    return fig


def chosen_windows(before: list[WindowResiduals], typical: int = TYPICAL_WINDOWS) -> list[tuple[int, str]]:
    """(index, label) of the held-out window of largest RMS residual and of ``typical`` windows of median RMS."""
    rms = np.array([float(np.sqrt(np.mean(np.square(w.residual)))) for w in before])
    order = np.argsort(rms)
    worst = int(order[-1])
    middle = len(order) // 2
    picks = [int(i) for i in order[max(middle - typical // 2, 0) :][:typical] if int(i) != worst]
    return [(worst, "worst window")] + [(i, "typical window") for i in picks]


def windows_chart(before: list[WindowResiduals], after: list[WindowResiduals] | None) -> Figure:
    """The rig file's and the corrected model's predictions against the measured angles over the worst and a few
    typical held-out windows, drawn relative to the measurement (prediction minus measured [counts]: the
    measurement is the zero line, its encoder step the shaded band of +-0.5 count)."""
    chosen = chosen_windows(before)
    fig = Figure(figsize=(10, 1.9 * len(chosen) + 0.5))
    axes = fig.subplots(len(chosen), 2, squeeze=False)
    for row, (index, label) in enumerate(chosen):
        window = before[index]
        time = np.asarray(window.time, float)
        for column, signal in enumerate(SIGNALS):
            ax = axes[row, column]
            ax.axhspan(-0.5, 0.5, color="0.92", lw=0)
            ax.axhline(0.0, color=MEASURED, lw=1.0, label="measured")
            ax.plot(time, -np.asarray(window.residual)[:, column], "--", lw=1.3, color=NOMINAL, label="rig file")
            if after is not None:
                corrected = -np.asarray(after[index].residual)[:, column]
                ax.plot(time, corrected, lw=1.3, color=CORRECTED, label="with the accepted effects")
            ax.set_title(f"{label}: {window.log_name}, {time[0]:.2f}-{time[-1]:.2f} s, {signal}", fontsize=8)
            ax.set_ylabel("predicted - measured\n[counts]", fontsize=7)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]", fontsize=8)
    _legend(fig, axes[0, 0])
    return fig


def chart_svgs(report: dict) -> dict[str, str]:
    """The report's own charts as {file name: SVG text} (those that have data)."""
    figures = {
        "gap.svg": gap_chart(report),
        "detection_limits.svg": limits_chart(report.get("detection_limits", [])),
        "localization.svg": localization_chart(report.get("localization", {})),
    }
    return {name: svg(fig) for name, fig in figures.items() if fig is not None}


__all__ = ["chart_svgs", "gap_chart", "limits_chart", "localization_chart", "windows_chart", "svg"]
