"""The diagnosis' output directory: ``report.json``, ``report.md``, ``report.html``, PNG plots, ``config.yaml``
(exact inputs with their sha256, versions, seeds, options), ``fitted_model.yaml`` (the fitted simulate config, so
``furuta-drake simulate --config fitted_model.yaml`` runs the corrected model) and ``fitted_rig.yaml`` (the rig
file with the accepted effects, to continue from); ``docs/diagnose.md`` describes each.

``report.json`` has the contract's keys in its order (later keys after them), every number a plain float
rounded to :data:`SIGNIFICANT_DIGITS` significant digits (non-finite as null), so the same inputs give
byte-identical files. The directory is written through :func:`furuta_drake.outputs.atomic_output_dir`: it
appears complete or not at all.

Effect curves (:func:`effect_curve`) read each effect's fitted parameters in SI units as the ranking lists them,
as the effect's own levels (not increments over the rig file): friction torque against velocity for the friction
effects, the command-to-torque map for dead zone, saturation and gain (a dead zone shifts the command towards
zero by its width, as Simulink's Dead Zone block), the spring torque -k (phi - phi_0) against phi, the unit step
response for lag and delay, and a bar chart of the parameters for the rest.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from furuta_drake.diagnosis.formatting import number, percent
from furuta_drake.diagnosis.gap.localize import band_power
from furuta_drake.diagnosis.logs.load import WindowResiduals
from furuta_drake.diagnosis.report import narrative, tables
from furuta_drake.diagnosis.report.charts import chart_svgs, svg, windows_chart
from furuta_drake.diagnosis.report.torque import plot_torque, torque_sentence
from furuta_drake.diagnosis.result import SPEC_KEYS
from furuta_drake.effects import surrogate_kernel as kernel
from furuta_drake.effects.surrogate import Model, applied_torque, spring_torque
from furuta_drake.effects.vocabulary import UNITS, apply_effects, effect_from_params, rig_model
from furuta_drake.outputs import atomic_output_dir, versions
from furuta_drake.rig import RigParameters
from furuta_drake.yamlio import dump_yaml_dataclass, to_plain

SIGNIFICANT_DIGITS = 6
_NUMBER = (int, float)
FRICTION_EFFECTS = (
    "arm_coulomb_friction",
    "arm_viscous_friction",
    "arm_stribeck",
    "friction_asymmetry",
    "pendulum_friction",
)
MAX_PLOT_POINTS = 20000  # per line of the residual plot; longer series are strided
MAX_RESIDUAL_LOGS = 6  # logs drawn in the residual plot


@dataclass
class EffectCurve:
    """One fitted-effect plot: named curves y(x), or bars when ``bars`` is true (x are then labels)."""

    effect: str
    title: str
    x_label: str
    y_label: str
    x: np.ndarray | list[str]
    curves: dict[str, np.ndarray] = field(default_factory=dict)
    bars: bool = False


def check_report(report: dict) -> None:
    """Raise ValueError unless ``report`` has every key of the spec's report.json with the spec's types."""
    _require(report, "", {"verdict": str, "effects": list, "gap": dict, "ranking": list, "localization": dict})
    if not all(isinstance(e, str) for e in report["effects"]):
        raise ValueError("report.effects must be a list of effect names")
    gap = report["gap"]
    _require(gap, "gap", {"metric": str, "nominal": dict, "with_effects": dict, "heldout_reduction": _NUMBER})
    for name in ("nominal", "with_effects"):
        _require(gap[name], f"gap.{name}", {"train": _NUMBER, "heldout": _NUMBER})
    for i, entry in enumerate(report["ranking"]):
        _require(
            entry,
            f"ranking[{i}]",
            {"effect": str, "params": dict, "heldout_gap": _NUMBER, "heldout_reduction": _NUMBER, "evidence": _NUMBER},
        )
        for key, value in entry["params"].items():
            if not _is_number(value) and not (key.split(".")[-1] == "form" and isinstance(value, str)):
                raise ValueError(f"report.ranking[{i}].params.{key} must be a number (or a form's name), got {value!r}")
    loc = report["localization"]
    _require(loc, "localization", {"signals": dict, "windows": list, "regimes": list, "frequency_bands": list})
    _require(loc["signals"], "localization.signals", {"theta": _NUMBER, "phi": _NUMBER})
    for i, w in enumerate(loc["windows"]):
        _require(w, f"localization.windows[{i}]", {"log": str, "start": _NUMBER, "end": _NUMBER, "why": str})
    for i, r in enumerate(loc["regimes"]):
        _require(r, f"localization.regimes[{i}]", {"regime": str, "share_of_gap": _NUMBER})
    for i, b in enumerate(loc["frequency_bands"]):
        _require(
            b, f"localization.frequency_bands[{i}]", {"low_hz": _NUMBER, "high_hz": _NUMBER, "share_of_gap": _NUMBER}
        )


def report_json(report: dict) -> str:
    """The deterministic text of report.json: spec keys first in the spec's order, floats rounded."""
    check_report(report)
    ordered = {key: report[key] for key in SPEC_KEYS}
    ordered.update((key, value) for key, value in report.items() if key not in SPEC_KEYS)
    return json.dumps(_canonical(ordered), indent=2, allow_nan=False) + "\n"


def input_record(
    *,
    rig_path: str | Path,
    train: Sequence[str | Path],
    heldout: Sequence[str | Path] = (),
    seeds: dict | None = None,
    options: dict | None = None,
) -> dict:
    """What config.yaml records: each input file with its sha256, the versions, the seeds and the options."""

    def entry(path):
        path = Path(path)
        return {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}

    return {
        "rig": entry(rig_path),
        "train": [entry(p) for p in train],
        "heldout": [entry(p) for p in heldout],
        "versions": versions(),
        "seeds": dict(seeds or {}),
        "options": dict(options or {}),
    }


def write_report(out_dir: str | Path, diagnosis, *, force: bool = False, protect: Sequence[str | Path] = ()) -> Path:
    """Write the whole output directory of ``diagnosis`` (a :class:`~furuta_drake.diagnosis.result.Diagnosis`
    with its artifacts) atomically (see :func:`write_report_files`); return its path. ``protect`` lists paths
    (the input logs and rig) that ``force`` must never delete."""
    with atomic_output_dir(out_dir, force=force, protect=protect) as staging:
        write_report_files(staging, diagnosis)
    return Path(out_dir)


def write_report_files(directory: Path, diagnosis) -> list[str]:
    """Write report.json, the plots, report.md, report.html, config.yaml, fitted_model.yaml and fitted_rig.yaml
    into an existing directory; return the written file names."""
    from furuta_drake.diagnosis.report.html import report_html

    directory = Path(directory)
    artifacts = diagnosis.artifacts
    text = report_json(diagnosis.to_json())
    report = json.loads(text)
    (directory / "report.json").write_text(text)
    charts = chart_svgs(report)
    for name, text in charts.items():
        (directory / name).write_text(text)
    figures = {}
    if artifacts.before:
        figures["windows.svg"] = (
            "Held-out windows, the worst and two typical: the rig file's (dashed) and the corrected (solid) "
            "predictions against the measured angles (the zero line; shaded: one encoder count)"
        )
        (directory / "windows.svg").write_text(svg(windows_chart(artifacts.before, artifacts.after)))
    figures["residuals.png"] = "Prediction residuals over time (worst windows shaded)"
    figures["residual_spectra.png"] = "Residual power spectral density, before and after the effects"
    plot_residuals(artifacts.before, artifacts.after, report["localization"]["windows"], directory / "residuals.png")
    plot_spectra(artifacts.before, artifacts.after, artifacts.noise_variance, directory / "residual_spectra.png")
    for curve in artifacts.curves:
        name = f"effect_{curve.effect}.png"
        plot_effect_curve(curve, directory / name)
        figures[name] = curve.title
    for joint, entry in report.get("unmodelled_torque", {}).items():
        plot_torque(joint, entry, artifacts.torque_scatter[joint], directory / entry["plot"])
        figures[entry["plot"]] = torque_sentence(joint, entry).rstrip(".")
    (directory / "config.yaml").write_text(
        yaml.safe_dump(to_plain(artifacts.record), sort_keys=False, default_flow_style=False)
    )
    (directory / "fitted_model.yaml").write_text(dump_yaml_dataclass(artifacts.fitted_config))
    (directory / "fitted_rig.yaml").write_text(
        _disturbance_comment(artifacts.fitted_rig) + dump_yaml_dataclass(artifacts.fitted_rig)
    )
    (directory / "report.md").write_text(report_markdown(report, figures))
    (directory / "report.html").write_text(report_html(report, directory, figures))
    written = ["config.yaml", "fitted_model.yaml", "fitted_rig.yaml", "report.md", "report.html"]
    return ["report.json", *charts, *figures, *written]


def report_markdown(report: dict, figures: dict[str, str]) -> str:
    """report.md in the page's order, answer first: the verdict sentence, the before/after chart, what to do next,
    how far to trust it, the accepted effects, what the logs could not see; then the evidence and the rule. The
    charts and figures are linked relatively."""
    gap = report["gap"]
    lines = ["# Sim-to-real gap diagnosis", "", f"**{narrative.verdict_sentence(report)}**", ""]
    lines += [
        f"Verdict `{report['verdict']}`. Held-out gap {number(gap['nominal']['heldout'])} counts with the rig file"
        + (
            f", {number(gap['with_effects']['heldout'])} with the accepted effects "
            f"({percent(gap['heldout_reduction'])} less)."
            if report.get("effects")
            else "."
        ),
        "",
    ]
    remaining = narrative.remaining_sentences(report)
    lines += [" ".join(remaining), ""] if remaining else []
    disturbance = narrative.disturbance_sentence(report)
    lines += [disturbance, ""] if disturbance else []
    lines += [
        "![Held-out error before and after, per log and signal](gap.svg)",
        "",
        "## What to do next",
        "",
        "Commands run from this report's folder.",
        "",
    ]
    for i, (what, command) in enumerate(narrative.next_steps(report), 1):
        lines += [f"{i}. {what}{':' if command else '.'}"] + (["", f"   `{command}`"] if command else []) + [""]
    lines += ["## How far to trust it", ""] + [f"- {sentence}" for sentence in narrative.trust_sentences(report)]
    lines += _table_markdown("The accepted effects", *tables.effects_table(report))
    if report["verdict"] == "unexplained":
        lines += ["", "## What the gap is", "", narrative.where_sentence(report["localization"])]
    for joint, fit in (report.get("unmodelled_torque") or {}).items():
        lines += ["", f"## The unmodelled torque on the {joint}", "", tables.unmodelled_sentence(joint, fit)]
        lines += _table_markdown("", *tables.unmodelled_table(fit))
        lines += ["", f"![Unmodelled torque on the {joint}]({fit['plot']})"] if fit.get("plot") else []
    header, rows = tables.beside_table(report)
    if rows:
        lines += ["", "## The listed effects beside the torque", "", tables.beside_sentence(report)]
        lines += _table_markdown("", header, rows)
    if report.get("detection_limits"):
        lines += ["", "## What these logs could not see", "", "![Detection limits](detection_limits.svg)", ""]
        lines += [f"- {narrative.limit_sentence(limit)}." for limit in report["detection_limits"]]
    return "\n".join(lines + _evidence_markdown(report, figures)) + "\n"


def _evidence_markdown(report: dict, figures: dict[str, str]) -> list[str]:
    lines = ["", "## The evidence"]
    if "windows.svg" in figures:
        lines += ["", f"![{figures['windows.svg']}](windows.svg)"]
    lines += _table_markdown("Steps", *tables.steps_table(report), level="###")
    (header, shown), (_, folded), failed, screened = tables.ranking_tables(report)
    lines += _table_markdown(f"Candidates tried (the best {tables.TOP_PER_STEP} of each step)", header, shown, "###")
    if folded:
        lines += ["", "<details><summary>The other candidates</summary>"] + _table_markdown("", header, folded)
        lines += ["", "</details>"]
    lines += ["", "Failed candidates (left out):", ""] + [f"- {line}" for line in failed] if failed else []
    lines += ["", "Screened out (not fitted further):", ""] + [f"- {line}" for line in screened] if screened else []
    lines += ["", "### Where the gap is", "", narrative.where_sentence(report["localization"]), ""]
    lines += ["![Where the gap is](localization.svg)"] + _localization_markdown(report["localization"])
    lines += ["", "### More figures", ""]
    for name, caption in figures.items():
        if name != "windows.svg":
            lines += [f"![{caption}]({name})", "", f"*{caption}.*", ""]
    lines += _table_markdown("How the verdict is reached", *tables.rule_table())
    lines += ["", report.get("rule", ""), "", f"Metric: {report['gap'].get('metric', '')}."]
    lines += [f"Held-out data: {report['holdout']}."] if report.get("holdout") else []
    lines += [f"Parameter intervals: {report['uncertainty']}."] if report.get("uncertainty") else []
    lines += ["", f"Why this verdict: {report['choice']}"] if report.get("choice") else []
    lines += [f"- Note: {note}" for note in report.get("notes") or []]
    return lines + [
        "",
        "## Files",
        "",
        "- `report.json`: this report for programs; `report.html`: this report in one file.",
        "- `config.yaml`: the exact inputs (paths and sha256), versions, seeds and options.",
        "- `fitted_model.yaml`: the fitted model as a simulate config "
        "(`furuta-drake simulate --config fitted_model.yaml`).",
        "- `fitted_rig.yaml`: the rig file with the accepted effects (or those beside a kept torque) in its "
        "`effects:` section, the torque in `unmodelled_torque:` (a further "
        "diagnosis continues from it: `furuta-drake diagnose --rig fitted_rig.yaml ...`).",
    ]


def _table_markdown(title: str, header: list[str], rows: list[list[str]], level: str = "##") -> list[str]:
    if not rows:
        return []
    lines = ["", f"{level} {title}"] if title else []
    lines += ["", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(_cell(cell) for cell in row) + " |" for row in rows]


def _localization_markdown(loc: dict) -> list[str]:
    after = loc.get("after")
    lines = [""]
    if "basis" in loc:
        lines += [f"Shares of the {loc['basis']}.", ""]
    header = "| signal | share (nominal) |" + (" share (with effects) |" if after else "")
    lines += [header, "|---|---:|" + ("---:|" if after else "")]
    for signal in ("theta", "phi"):
        row = f"| {signal} | {percent(loc['signals'][signal])} |"
        lines.append(row + (f" {percent(after['signals'][signal])} |" if after else ""))
    for title, block in (
        ("Worst time windows (nominal model):", loc),
        ("Worst time windows with the effects:", after or {}),
    ):
        if block.get("windows"):
            lines += ["", title, "", "| log | start [s] | end [s] | share of gap | why |", "|---|---:|---:|---:|---|"]
            lines += [
                f"| {_cell(w['log'])} | {number(w['start'])} | {number(w['end'])} | "
                f"{percent(w.get('share_of_gap'))} | {_cell(w['why'])} |"
                for w in block["windows"]
            ]
    lines += [
        "",
        "| regime | definition | share of samples | share of gap (nominal) |"
        + (" share of gap (with effects) |" if after else ""),
        "|---|---|---:|---:|" + ("---:|" if after else ""),
    ]
    after_regimes = {r["regime"]: r for r in after["regimes"]} if after else {}
    for r in loc["regimes"]:
        row = (
            f"| {r['regime']} | {_cell(r.get('definition', ''))} | {percent(r.get('share_of_samples'))} | "
            f"{percent(r['share_of_gap'])} |"
        )
        if after:
            row += f" {percent(after_regimes.get(r['regime'], {}).get('share_of_gap'))} |"
        lines.append(row)
    lines += [
        "",
        "| band [Hz] | share of gap (nominal) |" + (" share of gap (with effects) |" if after else ""),
        "|---|---:|" + ("---:|" if after else ""),
    ]
    after_bands = {(b["low_hz"], b["high_hz"]): b for b in after["frequency_bands"]} if after else {}
    for b in loc["frequency_bands"]:
        row = f"| {number(b['low_hz'])}-{number(b['high_hz'])} | {percent(b['share_of_gap'])} |"
        if after:
            row += f" {percent(after_bands.get((b['low_hz'], b['high_hz']), {}).get('share_of_gap'))} |"
        lines.append(row)
    return lines


def plot_residuals(
    before: list[WindowResiduals], after: list[WindowResiduals] | None, worst: list[dict], path: Path
) -> None:
    """One row per log, at most ``MAX_RESIDUAL_LOGS`` (those of the worst windows first): theta and phi residuals
    [counts] against time, worst windows shaded; the residuals with the effects dashed."""
    logs = list(dict.fromkeys([w["log"] for w in worst] + sorted({w.log_name for w in before})))
    logs = [log for log in logs if any(w.log_name == log for w in before)][:MAX_RESIDUAL_LOGS]
    fig = Figure(figsize=(10, 2.4 * len(logs) + 0.6))
    axes = fig.subplots(len(logs), 1, squeeze=False)[:, 0]
    for ax, log in zip(axes, logs):
        for windows, style, label in ((before, "-", "nominal"), (after or [], "--", "with effects")):
            time, residual = _joined([w for w in windows if w.log_name == log])
            if time.size == 0:
                continue
            for column, (signal, color) in enumerate((("theta", "tab:blue"), ("phi", "tab:orange"))):
                ax.plot(
                    time,
                    residual[:, column],
                    style,
                    color=color,
                    lw=0.7 if style == "-" else 0.9,
                    label=f"{signal}, {label}",
                )
        for w in worst:
            if w["log"] == log:
                ax.axvspan(w["start"], w["end"], color="tab:red", alpha=0.15, lw=0)
        ax.set_title(log, fontsize=9)
        ax.set_ylabel("residual [counts]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=4, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    _save(fig, path)


def plot_spectra(
    before: list[WindowResiduals], after: list[WindowResiduals] | None, noise_variance: float, path: Path
) -> None:
    """Residual power spectral density [counts^2/Hz] per signal, averaged over the windows, before and after,
    with the white sensor-noise level 2 s^2 dt."""
    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2)
    dt = float(np.median(np.concatenate([np.diff(w.time) for w in before])))
    for windows, style, label in ((before, "-", "nominal"), (after or [], "--", "with effects")):
        if not windows:
            continue
        centers, density = residual_psd(windows)
        for column, ax in enumerate(axes):
            ax.loglog(centers, np.maximum(density[:, column], 1e-12), style, label=label)
    for ax, signal in zip(axes, ("theta", "phi")):
        ax.axhline(2 * noise_variance * dt, color="0.5", lw=0.8, ls=":", label="encoder noise level")
        ax.set_title(f"{signal} residual", fontsize=9)
        ax.set_xlabel("frequency [Hz]")
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("PSD [counts$^2$/Hz]")
    axes[0].legend(fontsize=8)
    _save(fig, path)


def residual_psd(windows: list[WindowResiduals], bins: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres [Hz], one-sided PSD [counts^2/Hz] per signal (bins x 2)) over log-spaced bins from the
    longest window's resolution to the Nyquist frequency: per bin, the windows' periodogram power summed,
    divided by their sample count and the bin width (white noise of variance s^2 gives 2 s^2 dt). Windows of a
    coarser sample rate count only in the bins below their Nyquist frequency."""
    rates = [1.0 / float(np.median(np.diff(w.time))) for w in windows]
    longest = max(len(w.time) / rate for w, rate in zip(windows, rates))
    edges = np.concatenate([[0.0], np.geomspace(1.0 / longest, 0.5 * max(rates), bins)])
    power, samples = np.zeros((bins, 2)), np.zeros(bins)
    for w in windows:
        window_edges, band = band_power(w, 0.0, edges[:-1])
        power[: len(window_edges) - 1] += band
        samples[: len(window_edges) - 1] += len(w.time)
    centers = np.sqrt(np.maximum(edges[:-1], edges[1] / 2) * edges[1:])
    return centers, power / np.maximum(samples, 1)[:, None] / np.diff(edges)[:, None]


def effect_curve(effect: str, params: dict[str, float], rig: RigParameters) -> EffectCurve:
    """The plot of a fitted effect against the rig file's nominal model (see the module docstring): the nominal
    model and the model holding the effect in its own form (:func:`~.candidates.apply_effects`), evaluated by the
    model's laws (the kernel's friction, the actuator map, the spring)."""
    nominal = rig_model(rig)
    fitted = apply_effects(nominal, {effect: effect_from_params(effect, params)})
    if effect in FRICTION_EFFECTS:
        return _friction_curve(effect, nominal, fitted)
    if effect in ("actuator_deadzone", "actuator_saturation", "torque_gain_error"):
        command = np.linspace(-1.2 * rig.torque_limit, 1.2 * rig.torque_limit, 481)
        return EffectCurve(
            effect,
            f"Fitted {effect}: command to applied torque",
            "command [N m]",
            "applied torque [N m]",
            command,
            {"nominal": applied_torque(nominal, command), "fitted": applied_torque(fitted, command)},
        )
    if effect == "arm_spring":
        phi = np.linspace(-math.pi / 2, math.pi / 2, 361) + fitted.spring_equilibrium
        return EffectCurve(
            effect,
            "Fitted arm_spring: restoring torque",
            "phi [rad]",
            "spring torque [N m]",
            phi,
            {"nominal": spring_torque(nominal, phi), "fitted": spring_torque(fitted, phi)},
        )
    if effect in ("actuator_lag", "input_delay"):
        scale = max(fitted.lag, fitted.delay)
        time = np.linspace(0.0, max(5 * scale, 10 * rig.sample_period), 501)
        return EffectCurve(
            effect,
            f"Fitted {effect}: response to a unit step of the command",
            "time [s]",
            "applied / commanded torque",
            time,
            {"nominal": _step_response(nominal, time), "fitted": _step_response(fitted, time)},
        )
    names = [name for name, value in params.items() if not isinstance(value, str)]
    scales = [name for name in names if UNITS.get(name) == "-"]  # dimensionless: one axis, 1 = the rig file
    names = scales or names
    return EffectCurve(
        effect,
        f"Fitted {effect}: " + ("scales of the rig file's constants" if scales else "parameters (SI)"),
        "parameter",
        "value",
        names,
        {"fitted": np.array([params[n] for n in names], float)},
        bars=True,
    )


def _step_response(model: Model, time: np.ndarray) -> np.ndarray:
    """The applied torque after a unit step of the command at t = 0: the model's transport delay, then its
    first-order lag (none when the lag is 0)."""
    since = time - model.delay
    if model.lag <= 0:
        return (since >= 0).astype(float)
    return np.where(since >= 0, 1.0 - np.exp(-np.maximum(since, 0.0) / model.lag), 0.0)


def plot_effect_curve(curve: EffectCurve, path: Path) -> None:
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    if curve.bars:
        values = curve.curves["fitted"]
        ax.barh(curve.x, values, color="tab:blue")
        ax.invert_yaxis()
        for i, value in enumerate(values):
            ax.annotate(f" {value:.4g}", (value, i), va="center", fontsize=8)
    else:
        for label, y in curve.curves.items():
            ax.plot(
                curve.x,
                y,
                "--" if label == "nominal" else "-",
                color="0.4" if label == "nominal" else None,
                lw=1.2,
                label=label,
            )
        ax.legend(fontsize=8)
    ax.set_title(curve.title, fontsize=9)
    ax.set_xlabel(curve.y_label if curve.bars else curve.x_label)
    ax.set_ylabel(curve.x_label if curve.bars else curve.y_label)
    ax.grid(alpha=0.3)
    _save(fig, path)


def _friction_curve(effect: str, nominal: Model, fitted: Model) -> EffectCurve:
    """The joint's steady sliding friction torque against its velocity, the kernel's static law
    (:func:`~.surrogate_kernel.static_torque`: Coulomb level per direction, Stribeck peak, viscous), nominal and
    fitted."""
    joint = "pendulum" if effect == "pendulum_friction" else "arm"
    velocity = np.linspace(-2.0, 2.0, 801)

    def law(model: Model) -> np.ndarray:
        row = kernel.pack_friction(model.pendulum_friction if joint == "pendulum" else model.arm_friction)
        return -np.array([kernel.static_torque(v, row) for v in velocity])

    return EffectCurve(
        effect,
        f"Fitted {effect}: {joint} friction torque",
        f"{joint} velocity [rad/s]",
        "friction torque [N m]",
        velocity,
        {"nominal": law(nominal), "fitted": law(fitted)},
    )


def _joined(windows: list[WindowResiduals]) -> tuple[np.ndarray, np.ndarray]:
    """The windows in time order, separated by NaN rows (no line across a window boundary), strided to at most
    MAX_PLOT_POINTS samples."""
    if not windows:
        return np.zeros(0), np.zeros((0, 2))
    parts_t, parts_r = [], []
    for w in sorted(windows, key=lambda w: float(w.time[0])):
        parts_t += [np.asarray(w.time, float), [np.nan]]
        parts_r += [np.asarray(w.residual, float), np.full((1, 2), np.nan)]
    time, residual = np.concatenate(parts_t), np.concatenate(parts_r)
    stride = max(1, len(time) // MAX_PLOT_POINTS)
    return time[::stride], residual[::stride]


def _save(fig: Figure, path: Path) -> None:
    fig.tight_layout()
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110, metadata={"Software": None})


def _canonical(value):
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return float(f"{value:.{SIGNIFICANT_DIGITS}g}") if math.isfinite(value) else None
    return value


def _require(obj, where: str, keys: dict) -> None:
    if not isinstance(obj, dict):
        raise ValueError(f"report.{where} must be an object")
    for key, types in keys.items():
        if key not in obj:
            raise ValueError(f"report{'.' + where if where else ''} is missing {key!r}")
        value = obj[key]
        if types is _NUMBER:
            if not _is_number(value):
                raise ValueError(f"report.{where}.{key} must be a number, got {value!r}")
        elif not isinstance(value, types):
            raise ValueError(f"report{'.' + where if where else ''}.{key} must be a {types.__name__}")


def _is_number(value) -> bool:
    """Plain numbers; None stands for a non-finite figure (e.g. a diverged candidate's gap)."""
    return value is None or (
        isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    )


def _cell(text: str) -> str:
    """Text for a Markdown table cell (a literal | would end the cell)."""
    return str(text).replace("|", "\\|")


def _disturbance_comment(rig) -> str:
    """The comment that says how the rig file's ``disturbance:`` was read (none without one)."""
    if rig.disturbance is None:
        return ""
    return (
        "# disturbance: the arm torque the corrected model still misses on the held-out logs, read from the\n"
        "# equations of motion along them (the logged angles' smoothed accelerations against the model's), the\n"
        "# encoder's expected share taken out; simulations of this rig add a seeded draw of it\n"
    )
