"""The output directory of ``tune`` (``docs/tune.md`` describes every file): ``controller.yaml`` (the tuned
controller balancing the corrected model, a simulate config), ``nominal.yaml`` (the same with the nominal
controller), ``tune.json``, ``tune.md`` and ``tune.html`` (the answer first), ``balancing.png`` (the predicted
balancing, before and after) and ``config.yaml`` (the inputs with their sha256, versions, seeds, settings).
Written through :func:`~furuta_drake.outputs.atomic_output_dir`: it appears complete or not at all."""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import math
from pathlib import Path

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from furuta_drake.config import dump_config
from furuta_drake.diagnosis.report.html import STYLE
from furuta_drake.outputs import atomic_output_dir, versions
from furuta_drake.results import write_json
from furuta_drake.tune.controller import closed_loop, finite, torque_per_volt, volts_gain
from furuta_drake.tune.pipeline import DesignOutcome, Tuning
from furuta_drake.tune.robustness import MIN_DELAY_PERIODS, MIN_GAIN_DB

DESIGNS = ("nominal", "tuned")
FIGURES = ("theta_rms", "phi_rms", "limit_cycle_amplitude", "limit_cycle_frequency", "effort_rms")
UNITS = {"theta_rms": "rad", "phi_rms": "rad", "limit_cycle_amplitude": "rad", "limit_cycle_frequency": "Hz"}
UNITS["effort_rms"] = "N m"


def write_tune(out_dir: str | Path, tuning: Tuning, *, force: bool = False) -> Path:
    """Write every file of ``tuning`` into ``out_dir`` atomically; the diagnosis directory is protected from
    ``force``."""
    with atomic_output_dir(out_dir, force=force, protect=[tuning.inputs.directory]) as staging:
        document = tune_json(tuning)
        write_json(staging / "tune.json", document)
        settings = tuning.settings
        for name, outcome in (("controller.yaml", tuning.tuned), ("nominal.yaml", tuning.nominal)):
            config = closed_loop(tuning.world, outcome.controller, duration=settings.duration, seed=settings.seed)
            head = f"# furuta-drake tune: the {'tuned' if outcome is tuning.tuned else 'nominal'} controller "
            head += "balancing the corrected model; furuta-drake simulate --config runs it\n"
            (staging / name).write_text(head + dump_config(config))
        plot_balancing(tuning, staging / "balancing.png")
        blocks = report_blocks(json.loads((staging / "tune.json").read_text()))
        (staging / "tune.md").write_text(markdown(blocks))
        (staging / "tune.html").write_text(page(blocks, staging))
        (staging / "config.yaml").write_text(yaml.safe_dump(_config(tuning), sort_keys=False))
    return Path(out_dir)


def _config(tuning: Tuning) -> dict:
    inputs, settings = tuning.inputs, tuning.settings
    return {
        "diagnosis": {
            "path": str(inputs.directory),
            **{name: {"sha256": sha} for name, sha in inputs.sha256.items()},
        },
        "settings": {
            "duration_s": settings.duration,
            "weight_sets": [list(w) for w in settings.weight_sets],
            "observer_scales": list(settings.observer_scales),
            "compensation_gains": list(settings.compensation_gains),
            "finalists": settings.finalists,
            "disturbance_draws": settings.draws,
            "workers": settings.workers,
        },
        "seeds": {"disturbance_and_encoder_noise": settings.seed},
        "versions": versions(),
    }


def design_json(outcome: DesignOutcome, tuning: Tuning) -> dict:
    """One design's entry of ``tune.json``."""
    controller, world = outcome.controller, tuning.world
    dahl = controller.dahl
    coulomb = (0.5 * (dahl.coulomb_pos + dahl.coulomb_neg)) if dahl is not None and controller.compensation else 0.0
    label, worst = outcome.worst_corner()
    runs = {"the fit": outcome.prediction, **outcome.extremes}
    out = {
        "lqr_gain": list(controller.gain),
        "lqr": {"state_weights": list(controller.lqr.state_weights), "input_weight": controller.lqr.input_weight},
        "torque_limit": controller.torque_limit,
        "observer": controller.observer_dict(),
        "friction_compensation": {
            "arm_coulomb": coulomb,
            "gain": controller.compensation,
            **(
                {"coulomb_pos": dahl.coulomb_pos, "coulomb_neg": dahl.coulomb_neg}
                if dahl is not None and controller.compensation
                else {}
            ),
        },
        "predicted": _figures(outcome.prediction),
        "margins": {key: finite(value) for key, value in outcome.margins.as_dict().items() if key != "gain_range"},
        "gain_range": [finite(g) for g in outcome.margins.as_dict()["gain_range"]],
        "worst_corner": {"corner": label, "gain_db": finite(worst.gain_db), "delay_s": finite(worst.delay_s)},
        "predicted_over_intervals": {
            figure: _span([run.figures[figure] for run in runs.values() if run.balanced]) for figure in FIGURES
        },
        "extremes": {label: _figures(run) for label, run in outcome.extremes.items()},
        "robust": outcome.robust,
        "why_not_robust": outcome.failure,
        "family_member": outcome.member.as_dict() if outcome.member is not None else None,
    }
    volts = volts_gain(controller.gain, world)
    if volts is not None:
        out["lqr_gain_volts"] = volts
        out["arm_torque_gain"] = list(np.add(controller.gain, [0.0, 0.0, 0.0, world.rig.motor.back_emf_damping]))
    return out


def _figures(run) -> dict:
    if not run.balanced:
        return {"fell": run.fell}
    return {figure: finite(run.figures[figure]) for figure in FIGURES}


def _span(values: list[float]) -> list[float | None]:
    values = [v for v in values if math.isfinite(v)]
    return [min(values), max(values)] if values else [None, None]


def tune_json(tuning: Tuning) -> dict:
    """The ``tune.json`` object (docs/tune.md lists every key)."""
    inputs, model = tuning.inputs, tuning.model
    designs = {"nominal": design_json(tuning.nominal, tuning), "tuned": design_json(tuning.tuned, tuning)}
    for name, scales in tuning.under_disturbance.items():
        designs[name]["predicted_under_disturbance"] = {
            scale: {"fell": "fell"} if figures is None else {f: finite(figures[f]) for f in FIGURES}
            for scale, figures in scales.items()
        }
    disturbance = tuning.world.disturbance.arm_torque
    return {
        "sample_period": model.period,
        "designs": designs,
        "disturbance": None if disturbance is None else dataclasses.asdict(disturbance),
        "robust_over_intervals": tuning.tuned.robust,
        "requirements": {"min_gain_db": MIN_GAIN_DB, "min_delay_s": MIN_DELAY_PERIODS * model.period},
        "design_model": {
            "states": model.size,
            "delay_s": model.delay,
            "lag_s": model.lag,
            "linear_corners": len(tuning.tuned.corner_margins),
            "effect_extremes": list(tuning.tuned.extremes),
        },
        "diagnosis": {
            "directory": str(inputs.directory),
            "verdict": inputs.verdict,
            "effects": {
                name: {
                    "form": effect.form,
                    "params": dict(zip(_params(name, effect), effect.values)),
                    "params_ci": {p: list(inputs.intervals[(name, p)]) for p in _params(name, effect)},
                }
                for name, effect in inputs.accepted.items()
            },
            "unmodelled_torque": {joint: entry.get("expression") for joint, entry in inputs.torque.items()},
        },
        "command_unit": "V" if torque_per_volt(tuning.world) is not None else "N m",
        "search": {
            "most_drake_runs": tuning.budget,
            "finalists": tuning.settings.finalists,
            "disturbance_draws": tuning.settings.draws if tuning.under_disturbance else 1,
        },
        "swingup": (
            None
            if tuning.swingup is None
            else {"configured": tuning.settings.swingup.as_dict(), "designs": tuning.swingup}
        ),
        "candidates": tuning.candidates,
        "duration_s": tuning.settings.duration,
        "seed": tuning.settings.seed,
        "notes": tuning.notes,
    }


def _params(name, effect) -> tuple[str, ...]:
    from furuta_drake.effects.vocabulary import CANDIDATES

    return CANDIDATES[name].form(effect.form).params


def plot_balancing(tuning: Tuning, path: Path) -> None:
    """The predicted balancing of both designs at the fit: the encoder's theta and phi and the command."""
    figure = Figure(figsize=(9, 7), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(3, 1, sharex=True)
    for name, outcome, style in (("nominal", tuning.nominal, "C3"), ("tuned", tuning.tuned, "C0")):
        result = outcome.prediction.result
        if result is None:
            axes[0].set_title(f"the {name} design fell: {outcome.prediction.fell}", fontsize=9)
            continue
        for ax, values in zip(axes, (result.measured[:, 0], result.measured[:, 1], result.torque)):
            ax.plot(result.time, values, style, lw=0.8, label=name)
    for ax, label in zip(axes, ("theta [rad]", "phi [rad]", "command [N m]")):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    steady = tuning.settings.duration / 2
    for ax in axes:
        ax.axvspan(steady, tuning.settings.duration, color="0.9", zorder=0)
    axes[-1].set_xlabel("time [s] (shaded: the steady part the figures are read on)")
    figure.suptitle("Predicted balancing on the corrected model: nominal and tuned designs")
    figure.savefig(path, dpi=110)


# --- the report: blocks rendered as Markdown and as one self-contained HTML page -------------------------------


def _mrad(value) -> str:
    return "-" if value is None else f"{1e3 * value:.3g} mrad"


def _ms(seconds) -> str:
    return "-" if seconds is None else f"{1e3 * seconds:.3g}"


def _observer_text(observer: dict) -> str:
    if observer["kind"] == "hg":
        text = f"HG, eps {_ms(observer['eps_theta'])} ms (theta), {_ms(observer['eps_phi'])} ms (phi)"
    else:
        text = "VFE, eigenvalues " + ", ".join(f"{v:.3g}" for v in observer["eigenvalues"]) + " rad/s"
    dahl = observer.get("dahl")
    if dahl:
        text += (
            f"; Dahl observer Fc+ {1e3 * dahl['coulomb_pos']:.3g} mN m, Fc- {1e3 * dahl['coulomb_neg']:.3g} mN m, "
            f"sigma0 {dahl['sigma0']:.3g} N m/rad"
        )
    return text


def _change(before, after) -> str:
    if before is None or after is None or before == 0:
        return "-"
    return f"{100.0 * (after - before) / before:+.0f} %"


def _number(value, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    return f"{value:.{digits}g}"


def answer(document: dict) -> str:
    """The answer in a few sentences: what changes, by how much, how sure."""
    nominal, tuned = document["designs"]["nominal"], document["designs"]["tuned"]
    p0, p1 = nominal["predicted"], tuned["predicted"]
    gain = ", ".join(f"{k:.4g}" for k in tuned["lqr_gain"])
    compensation = tuned["friction_compensation"]
    kind = tuned["observer"]["kind"].upper()
    what = f"The tuned controller (gain K = [{gain}] on [theta, phi, theta_dot, phi_dot], {kind} observer"
    what += (
        f", friction compensation at K_sigma = {compensation['gain']:g} of the fitted "
        f"{1e3 * compensation['arm_coulomb']:.3g} mN m Coulomb friction)"
        if compensation["gain"]
        else ", no friction compensation)"
    )
    if tuned.get("family_member") is None:
        what = (
            "tune keeps the nominal design: no design of the family predicts a smaller theta RMS and limit cycle "
            f"over the parameters' 95 % intervals ({kind} observer, K = [{gain}])"
        )
    if "fell" in p1:
        return what + f" falls on the corrected model: {p1['fell']}."
    if "fell" in p0:
        how = (
            f" balances the corrected model (theta RMS {_mrad(p1['theta_rms'])}, limit cycle "
            f"{_mrad(p1['limit_cycle_amplitude'])}), where the nominal design falls ({p0['fell']})."
        )
    else:
        a0, a1 = p0["limit_cycle_amplitude"], p1["limit_cycle_amplitude"]
        how = (
            f" is predicted to take the balancing limit cycle from {_mrad(a0)} to {_mrad(a1)} ({_change(a0, a1)})"
            f" and theta's RMS from {_mrad(p0['theta_rms'])} to {_mrad(p1['theta_rms'])} "
            f"({_change(p0['theta_rms'], p1['theta_rms'])}) on the corrected model."
        )
    worst = tuned["worst_corner"]
    span = tuned["predicted_over_intervals"]["limit_cycle_amplitude"]
    sure = (
        f" Over the parameters' 95 % intervals it keeps a gain margin of at least "
        f"{_number(worst['gain_db'], 3)} dB and a delay margin of {_ms(worst['delay_s'])} ms"
        f" (worst corner: {worst['corner'] or 'the fit'}; required {document['requirements']['min_gain_db']:g} dB and "
        f"{1e3 * document['requirements']['min_delay_s']:g} ms), and its limit cycle stays within "
        f"{_mrad(span[0])} to {_mrad(span[1])} at the accepted effects' extremes."
    )
    return what + how + sure + _pushed(document)


def _pushed(document: dict) -> str:
    """The answer's sentence on the rig's disturbance ('' without one)."""
    disturbance = document.get("disturbance")
    if not disturbance or not disturbance["arm_torque_rms"]:
        return ""
    twice = [document["designs"][name].get("predicted_under_disturbance", {}).get("2", {}) for name in DESIGNS]
    text = (
        f" Every figure is predicted under the rig's disturbance as the diagnosis read it, "
        f"{1e3 * disturbance['arm_torque_rms']:.3g} mN m RMS on the arm"
    )
    if all("theta_rms" in figures for figures in twice):
        text += (
            f"; at twice that, theta's RMS would be {_mrad(twice[0]['theta_rms'])} with the nominal design and "
            f"{_mrad(twice[1]['theta_rms'])} with the tuned one"
        )
    return text + "."


def report_blocks(document: dict) -> list[tuple]:
    """The report as blocks: ('h1'|'h2'|'p', text), ('table', header, rows), ('img', file, caption)."""
    blocks = [("h1", "Controller tuned from the diagnosis"), ("p", answer(document))]
    blocks += _prediction_blocks(document) + _disturbance_blocks(document) + _swingup_blocks(document)
    blocks += _controller_blocks(document)
    blocks += _evidence_blocks(document)
    return blocks + [("p", f"Note: {note}") for note in document["notes"]]


def _prediction_blocks(document: dict) -> list[tuple]:
    nominal, tuned = document["designs"]["nominal"], document["designs"]["tuned"]
    rows = []
    for figure in FIGURES:
        a, b = nominal["predicted"].get(figure), tuned["predicted"].get(figure)
        span = tuned["predicted_over_intervals"][figure]
        rows.append(
            [
                f"{figure} [{UNITS[figure]}]",
                _number(a),
                _number(b),
                _change(a, b),
                f"{_number(span[0])} to {_number(span[1])}",
            ]
        )
    header = ["design", "gain margin [dB]", "delay margin [ms]", "worst corner", "its gain margin [dB]"]
    margins = [
        [
            name,
            _number(d["margins"]["gain_db"], 3),
            _ms(d["margins"]["delay_s"]),
            d["worst_corner"]["corner"] or "the fit",
            _number(d["worst_corner"]["gain_db"], 3),
            _ms(d["worst_corner"]["delay_s"]),
        ]
        for name, d in document["designs"].items()
    ]
    return [
        ("h2", "Predicted balancing on the corrected model"),
        ("table", ["figure", "nominal", "tuned", "change", "tuned over the intervals"], rows),
        ("img", "balancing.png", "The predicted balancing of both designs from the same seeded disturbance"),
        ("h2", "Margins of the sampled loop (state feedback, loop broken at the plant input)"),
        ("table", [*header, "its delay margin [ms]"], margins),
    ]


def _disturbance_blocks(document: dict) -> list[tuple]:
    """The disturbance the designs were judged under and both designs at each of its levels (none: no block)."""
    disturbance = document.get("disturbance")
    if not disturbance or not disturbance["arm_torque_rms"]:
        return []
    ci = disturbance.get("ci") or [None, None]
    text = (
        f"Every prediction above runs under the rig's disturbance as the diagnosis read it: an arm torque of "
        f"{_number(disturbance['arm_torque_rms'], 3)} N m RMS (95 % interval {_number(ci[0], 3)} to "
        f"{_number(ci[1], 3)}), 90 % of its power below {disturbance['bandwidth_hz']:.3g} Hz, each figure the mean "
        f"over {document['search']['disturbance_draws']} seeded draws of it. Both designs at other levels:"
    )
    rows = []
    for name, design in document["designs"].items():
        for scale, figures in design.get("predicted_under_disturbance", {}).items():
            rows.append(
                [name, f"x {scale}", *[_number(figures.get(f)) for f in ("theta_rms", "limit_cycle_amplitude")]]
            )
    header = ["design", "disturbance", "theta_rms [rad]", "limit_cycle_amplitude [rad]"]
    return [("h2", "Under the rig's disturbance"), ("p", text), ("table", header, rows)]


def _catch_text(run: dict) -> str:
    if run["catch_time_s"] is not None:
        return f"{run['catch_time_s']:.3g} s"
    return f"no catch ({run['fell']})" if run["fell"] else "no catch"


def _swingup_blocks(document: dict) -> list[tuple]:
    """The catch time of each design behind the configured swing-up (none configured: no block)."""
    swingup = document.get("swingup")
    if swingup is None:
        return []
    configured = swingup["configured"]
    rows = []
    for name, design in swingup["designs"].items():
        span = design["catch_time_over_intervals"]
        rows.append(
            [
                name,
                _catch_text(design["at_fit"]),
                f"{span[0]:.3g} to {span[1]:.3g} s" if span else "no catch at some extreme",
                "; ".join(f"{label}: {_catch_text(run)}" for label, run in design["extremes"].items()) or "-",
            ]
        )
    return [
        ("h2", "Swing-up catch time"),
        (
            "p",
            f"Each design's gain behind the configured energy swing-up on the corrected model, from theta = "
            f"{configured['theta0']:.3g} rad at rest, for {configured['duration_s']:g} s (velocities from "
            f"{configured['velocity_source']}): the time of the last hand-over to the LQR.",
        ),
        ("table", ["design", "catch time at the fit", "over the intervals", "at the effect extremes"], rows),
    ]


def _controller_blocks(document: dict) -> list[tuple]:
    designs = document["designs"]
    rows = [
        [
            name,
            ", ".join(f"{k:.4g}" for k in d["lqr_gain"]),
            _observer_text(d["observer"]),
            _number(d["friction_compensation"]["gain"]),
            "yes" if d["robust"] else f"no: {d['why_not_robust']}",
        ]
        for name, d in designs.items()
    ]
    blocks = [
        ("h2", "The controllers"),
        ("table", ["design", "K [N m per rad, rad/s]", "observer", "compensation K_sigma", "robust"], rows),
    ]
    if "lqr_gain_volts" in designs["tuned"]:
        volts = {name: ", ".join(f"{k:.4g}" for k in d["lqr_gain_volts"]) for name, d in designs.items()}
        blocks.append(
            (
                "p",
                "In volts (V = -K_V x, the torque gain over kt / R; the motor's back-EMF adds kt ke / R on phi_dot to "
                f"the net arm torque): tuned K_V = [{volts['tuned']}], nominal K_V = [{volts['nominal']}].",
            )
        )
    return blocks


def _evidence_blocks(document: dict) -> list[tuple]:
    extremes = [
        [label, name, *([run["fell"]] + [""] * 4 if "fell" in run else [_number(run[f]) for f in FIGURES])]
        for name, d in document["designs"].items()
        for label, run in d["extremes"].items()
    ]
    candidates = [_candidate_row(c) for c in document["candidates"]]
    model = document["design_model"]
    return [
        ("h2", "At the accepted effects' extremes"),
        ("table", ["extreme", "design", *FIGURES], extremes),
        ("h2", "Candidates tried"),
        (
            "p",
            f"The family of designs on the corrected model (at most {document['search']['most_drake_runs']} Drake "
            "runs): each judged at the fit by theta's RMS and the limit cycle against the nominal design's, the "
            f"{document['search']['finalists']} best again at the effect extremes by the worst case over the "
            "intervals; the nominal design competes too and wins ties.",
        ),
        (
            "table",
            [
                "Q_theta, Q_phi, R scales",
                "observer, scale",
                "K_sigma",
                "limit cycle at the fit [rad]",
                "theta RMS at the fit [rad]",
                "worst limit cycle, theta RMS over the intervals [rad]",
                "outcome",
            ],
            candidates,
        ),
        ("h2", "What it rests on"),
        (
            "p",
            f"The diagnosis in {document['diagnosis']['directory']} (verdict {document['diagnosis']['verdict']}); the "
            f"design model has {model['states']} states (input delay {_ms(model['delay_s'])} ms, actuator lag "
            f"{_ms(model['lag_s'])} ms) at a {1e3 * document['sample_period']:g} ms period; every figure is a Drake "
            f"run of {document['duration_s']:g} s on the corrected model from the same seeded disturbance (seed "
            f"{document['seed']}), read on its last half with the rig's encoders.",
        ),
    ]


def _candidate_row(c: dict) -> list[str]:
    """One row of the candidates' table: a family member, or the nominal design."""
    outcome = "chosen" if c.get("chosen") else c.get("rejected") or c.get("fell") or "not chosen"
    if c.get("design") == "nominal":
        return ["nominal design", "-", "-", "-", "-", "see above", outcome]
    predicted, worst = c.get("predicted") or {}, c.get("worst_over_intervals") or {}
    return [
        f"{c['theta_weight_scale']:g}, {c['phi_weight_scale']:g}, {c['input_weight_scale']:g}",
        f"{(c.get('observer_kind') or '-').upper()}, {_number(c['observer_scale'])}",
        _number(c["compensation_gain"]),
        _number(predicted.get("limit_cycle_amplitude")),
        _number(predicted.get("theta_rms")),
        f"{_number(worst.get('limit_cycle_amplitude'))}, {_number(worst.get('theta_rms'))}" if worst else "-",
        outcome,
    ]


def markdown(blocks: list[tuple]) -> str:
    lines = []
    for block in blocks:
        kind = block[0]
        if kind == "h1":
            lines += [f"# {block[1]}", ""]
        elif kind == "h2":
            lines += [f"## {block[1]}", ""]
        elif kind == "p":
            lines += [block[1], ""]
        elif kind == "img":
            lines += [f"![{block[2]}]({block[1]})", ""]
        else:
            header, rows = block[1], block[2]
            lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            lines += ["| " + " | ".join(str(cell).replace("|", "/") for cell in row) + " |" for row in rows] + [""]
    return "\n".join(lines)


def page(blocks: list[tuple], directory: Path) -> str:
    """One self-contained HTML page (figures inline, no external resource)."""
    body = []
    for block in blocks:
        kind = block[0]
        if kind == "h1":
            body.append(f"<h1>{html.escape(block[1])}</h1>")
        elif kind == "h2":
            body.append(f"<h2>{html.escape(block[1])}</h2>")
        elif kind == "p":
            body.append(f"<p>{html.escape(block[1])}</p>")
        elif kind == "img":
            data = base64.b64encode((directory / block[1]).read_bytes()).decode()
            body.append(
                f'<figure><img src="data:image/png;base64,{data}" alt="{html.escape(block[2])}">'
                f"<figcaption>{html.escape(block[2])}</figcaption></figure>"
            )
        else:
            head = "".join(f"<th>{html.escape(str(h))}</th>" for h in block[1])
            rows = "".join(
                "<tr>" + "".join(f"<td>{html.escape(str(cell))}</td>" for cell in row) + "</tr>" for row in block[2]
            )
            body.append(f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table></div>')
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>furuta-drake tune</title>'
        f"<style>{STYLE}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n"
    )


__all__ = ["write_tune", "tune_json", "report_blocks", "answer", "markdown", "page"]
