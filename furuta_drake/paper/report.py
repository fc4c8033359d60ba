"""The files of ``furuta-drake reproduce``: the paper's tables and figures next to the simulated rig's.

``run_reproduction`` runs the experiments of :mod:`furuta_drake.paper.reproduce` that ``settings.only`` selects and
writes, into a directory that appears complete or not at all: ``table1.csv``, ``table2.csv`` (and the
fairness sweep ``observer_sweep.csv``), ``fig3.png`` ... ``fig7.png``, ``adaptation.json``, ``report.md``,
``config.yaml`` (the simulated rig, a ``simulate`` config), ``reproduction.yaml`` (these settings and the
tuned observers) and every run's raw log with its config in ``logs/``; ``beyond`` adds ``beyond.md`` and the
plots of the studies of :mod:`furuta_drake.paper.studies` (the open problems of the paper's Sec. VI-VII). CSV and JSON
files are byte-identical for the same settings.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from furuta_drake.config import SimulationConfig, dump_config
from furuta_drake.errors import ConfigError
from furuta_drake.outputs import atomic_output_dir, versions
from furuta_drake.paper import reproduce
from furuta_drake.plotting import (
    plot_control_signals,
    plot_fig5,
    plot_friction_estimates,
    plot_k_sigma,
    plot_observer_sweep,
    plot_velocity_estimates,
)
from furuta_drake.results import config_yaml_with_provenance, write_json, write_log_csv, write_table_csv
from furuta_drake.yamlio import dump_yaml_dataclass

EXPERIMENTS = ("table1", "table2", "fig5", "fig6", "fig7", "beyond", "real")
PAPER_EXPERIMENTS = EXPERIMENTS[:5]
BEYOND_STUDIES = (
    "pendulum_observer_study",
    "parameter_adaptation_study",
    "lugre_observer_study",
    "stability_study",
    "swingup_study",
)


@dataclass
class ReproductionSettings:
    """What ``furuta-drake reproduce`` runs: the experiments, the seed and the run lengths."""

    only: list[str] = field(default_factory=lambda: list(PAPER_EXPERIMENTS))
    seed: int = 0
    table_duration: float = 20.0  # [s] Sec. IV's two 20 s tests; also each run of Fig. 5
    adaptation_duration: float = 40.0  # [s] Figs. 6-7, adaptation enabled at 7.8 s
    small_beyond: bool = False  # the beyond-the-paper studies in their short form
    small_real: bool = False  # the real-rig studies in their short form

    def validate(self) -> None:
        unknown = sorted(set(self.only) - set(EXPERIMENTS))
        if unknown or not self.only:
            raise ConfigError(f"--only: unknown experiment(s) {unknown}; choose among {', '.join(EXPERIMENTS)}")
        if not self.table_duration >= 2 * reproduce.TRANSIENT:
            raise ConfigError(
                f"--table-duration must be >= {2 * reproduce.TRANSIENT:g} s (the first "
                f"{reproduce.TRANSIENT:g} s are a transient), got {self.table_duration!r}"
            )
        if not self.adaptation_duration > reproduce.ADAPTATION_ENABLE_TIME + 3.0:
            raise ConfigError(
                f"--adaptation-duration must exceed {reproduce.ADAPTATION_ENABLE_TIME + 3.0:g} s "
                f"(adaptation starts at {reproduce.ADAPTATION_ENABLE_TIME:g} s), got "
                f"{self.adaptation_duration!r}"
            )


def run_reproduction(
    settings: ReproductionSettings, out: str | Path, *, force: bool = False, progress=None, real=None
) -> dict:
    """Run the selected experiments and write their files into ``out``; returns the figures of report.md.

    ``progress(message)`` is called after each simulation or sweep. ``real``: the real-rig experiment
    (:func:`furuta_drake.real_rig.report.reproduce_real`, which sits above this package), needed when
    ``settings.only`` holds ``real``."""
    settings.validate()
    only = set(settings.only)
    if "real" in only and real is None:
        raise ValueError("run_reproduction: the real experiment needs real=furuta_drake.real_rig.report.reproduce_real")
    started = time.perf_counter()
    base = reproduce.paper_rig_config(seed=settings.seed, duration=settings.table_duration)
    figures: dict = {}
    with atomic_output_dir(out, force=force) as staging:
        logs = staging / "logs"
        logs.mkdir()
        (staging / "config.yaml").write_text(config_yaml_with_provenance(base))
        tuned = base
        if only & {"table1", "table2"}:
            tuned = _run_tables(base, staging, figures, progress)
        if "fig5" in only:
            _run_fig5(base, staging, figures, progress)
        if only & {"fig6", "fig7"}:
            _run_adaptation(base, settings, staging, figures, progress)
        if only & {"fig5", "fig6", "fig7"}:
            write_json(staging / "adaptation.json", _adaptation_json(figures))
        if "beyond" in only:
            figures["beyond"] = _run_beyond_into(settings, staging, progress)
        real_text = real(settings, staging, figures, progress) if "real" in only else None
        (staging / "reproduction.yaml").write_text(_settings_yaml(settings, tuned))
        figures["wall_time_s"] = time.perf_counter() - started
        text = reproduction_markdown(figures, settings) if only - {"real"} else ""
        if real_text is not None:
            text += ("\n" if text else "") + real_text
        (staging / "report.md").write_text(text)
        if "beyond" in only:
            (staging / "beyond.md").write_text(studies_markdown(figures["beyond"], settings))
    return figures


def _run_tables(base: SimulationConfig, staging: Path, figures: dict, progress) -> SimulationConfig:
    """Tables I-II with the fairness sweep: their files, logs and figures; returns the config with the tuned
    observers."""
    runs = reproduce.run_table_experiments(base, progress=progress)
    tuned = runs.config
    figures["table1"] = reproduce.table1(runs)
    figures["table2"] = reproduce.table2(runs)
    figures["observer_sweep"] = runs.sweep
    _write_tables(staging, runs, figures)
    _write_run(staging / "logs", "table_lqr_on_hg", runs.hg_run, reproduce.with_velocity_source(tuned, "hg"))
    _write_run(staging / "logs", "table_lqr_on_vfe", runs.vfe_run, reproduce.with_velocity_source(tuned, "vfe"))
    return tuned


def _run_fig5(base: SimulationConfig, staging: Path, figures: dict, progress) -> None:
    """Fig. 5, the friction observed with two Dahl sets: its plot, logs and steady values."""
    outcome = reproduce.fig5_experiment(base, progress=progress)
    figures["fig5"] = {name: run["steady"] for name, run in outcome.items()}
    plot_fig5(
        {f"{name}: Fc and sigma0 x {run['factor']:g}": run["result"] for name, run in outcome.items()},
        (reproduce.ARM_COULOMB_POS, reproduce.ARM_COULOMB_NEG),
        staging / "fig5.png",
    )
    for name, run in outcome.items():
        _write_run(staging / "logs", f"fig5_{name}", run["result"], run["config"])


def _run_adaptation(
    base: SimulationConfig, settings: ReproductionSettings, staging: Path, figures: dict, progress
) -> None:
    """Figs. 6-7, the K_sigma adaptation (Eq. 18): the selected plots, the log and the summary."""
    only = set(settings.only)
    adaptation = reproduce.adaptation_experiment(base, settings.adaptation_duration, progress=progress)
    figures["adaptation"] = adaptation["summary"]
    result = adaptation["result"]
    if "fig6" in only:
        plot_k_sigma(result, reproduce.ADAPTATION_ENABLE_TIME, reproduce.PAPER_K_SIGMA_RANGE, staging / "fig6.png")
    if "fig7" in only:
        plot_friction_estimates(
            result,
            staging / "fig7.png",
            title="Fig. 7: adapted friction estimate (adaptation on at 7.8 s)",
            calibrated=(reproduce.ARM_COULOMB_POS, reproduce.ARM_COULOMB_NEG),
        )
    _write_run(staging / "logs", "adaptation", result, adaptation["config"])


def _run_beyond_into(settings: ReproductionSettings, staging: Path, progress) -> list:
    """The studies of :func:`run_beyond`, their plots, logs and ``beyond.csv`` written; returns the studies."""
    studies = run_beyond(settings.seed, settings.small_beyond, progress)
    for study in studies:
        for stem, figure in study.figures.items():
            figure.savefig(staging / f"beyond_{stem}.png", dpi=110)
        for name, result in study.logs.items():
            write_log_csv(result, staging / "logs" / f"beyond_{name}.csv")
    write_table_csv([{"study": study.title, **row} for study in studies for row in study.rows], staging / "beyond.csv")
    return studies


def run_beyond(seed: int, small: bool, progress=None) -> list:
    """Every study of :mod:`furuta_drake.paper.studies` (``BEYOND_STUDIES``), each on the paper's rig and ``seed``."""
    import importlib

    studies = []
    for name in BEYOND_STUDIES:
        studies.append(importlib.import_module(f"furuta_drake.paper.studies.{name}").study(seed=seed, small=small))
        reproduce.report_progress(progress, f"beyond: {name}")
    return studies


def studies_markdown(studies: list, settings: ReproductionSettings) -> str:
    """beyond.md: each study's table (the paper's method next to the extension) and what it shows."""
    lines = [
        "# Beyond the paper: the open problems of its Sections VI-VII",
        "",
        f"Each study runs the paper's method and the extension on the same simulated rig and seed "
        f"({settings.seed}){' in its short form' if settings.small_beyond else ''}; `beyond.csv` has the "
        f"numbers, `beyond_*.png` the plots, `logs/beyond_*.csv` the raw logs.",
        "",
    ]
    for study in studies:
        lines += [
            f"## {study.title}",
            "",
            study.summary,
            "",
            "| metric | paper's method | extension | unit | paper / extension | note |",
            "|---|---|---|---|---|---|",
        ]
        for row in study.rows:
            paper, extension = row["paper"], row["extension"]
            ratio = f"{paper / extension:.2f}" if paper is not None and extension else ""
            lines.append(
                f"| {row['metric']} | {_number(paper)} | {_number(extension)} | {row['unit']} | {ratio} | "
                f"{row['note']} |"
            )
        lines.append("")
    return "\n".join(lines) + "\n"


def _number(value) -> str:
    return "" if value is None else f"{value:.4g}"


def _write_tables(staging: Path, runs: reproduce.TableRuns, figures: dict) -> None:
    write_table_csv(figures["table1"], staging / "table1.csv")
    write_table_csv(figures["table2"], staging / "table2.csv")
    write_table_csv(figures["observer_sweep"], staging / "observer_sweep.csv")
    plot_observer_sweep(figures["observer_sweep"], staging / "observer_sweep.png")
    run = runs.vfe_run
    reference = reproduce.velocity_references(run, runs.config)["butterworth"]
    plot_velocity_estimates(run, reference, staging / "fig3.png")
    plot_control_signals({"LQR on HG": runs.hg_run, "LQR on VFE": runs.vfe_run}, staging / "fig4.png")


def _write_run(logs: Path, name: str, result, config) -> None:
    write_log_csv(result, logs / f"{name}.csv")
    (logs / f"{name}.yaml").write_text(dump_config(config))


def _adaptation_json(figures: dict) -> dict:
    adaptation = figures.get("adaptation", {})
    keys = ("K_sigma_plus", "K_sigma_minus", "friction_pos", "friction_neg", "theta_abs_max", "enable_time")
    out = {key: adaptation.get(key) for key in keys}
    out["fig5"] = {
        name: {quantity: steady_values(steady, quantity) for quantity in ("F_hat", "F_hat_plus_eps", "true")}
        for name, steady in figures.get("fig5", {}).items()
    }
    return out


def steady_values(steady: dict, quantity: str) -> dict:
    """{'pos': ..., 'neg': ...} of one quantity of ``reproduce.steady_friction_values``."""
    return {direction: steady[direction][quantity] for direction in ("pos", "neg")}


def _settings_yaml(settings: ReproductionSettings, tuned) -> str:
    """reproduction.yaml: the settings and the observers the fairness sweep chose, headed by the versions."""
    header = "".join(f"# {name} {version}\n" for name, version in versions().items())
    return header + dump_yaml_dataclass(
        {"settings": settings, "tuned_observers": {"hg": tuned.observers.hg, "vfe": tuned.observers.vfe}}
    )


def reproduction_markdown(figures: dict, settings: ReproductionSettings) -> str:
    """report.md: every figure next to the paper's, with the ratio, and the targets of the reproduction."""
    lines = [
        "# Reproduction of Lenain et al., *A Velocity Observer Based on Friction Adaptation*",
        "",
        f"Simulated Lund rig (`config.yaml`), seed {settings.seed}; Tables I-II and Fig. 5 from "
        f"{settings.table_duration:g} s runs, Figs. 6-7 from a {settings.adaptation_duration:g} s run; the "
        f"first {reproduce.TRANSIENT:g} s of every run are dropped from the statistics. Wall time "
        f"{figures['wall_time_s']:.0f} s.",
        "",
    ]
    if "table1" in figures:
        lines += _table1_lines(figures["table1"])
    if "table2" in figures:
        lines += _table2_lines(figures["table2"], figures["observer_sweep"])
    if "fig5" in figures:
        lines += _fig5_lines(figures["fig5"])
    if "adaptation" in figures:
        lines += _adaptation_lines(figures["adaptation"])
    if "beyond" in figures:
        lines += [
            "## Beyond the paper",
            "",
            "The studies of the paper's open problems (Sec. VI-VII) are in `beyond.md`.",
            "",
        ]
    return "\n".join(lines) + "\n"


def _table1_lines(table1: list[dict]) -> list[str]:
    """Table I (squared control errors) and the paper's point: similar control accuracy with HG and VFE."""
    lines = _table_section("Table I: squared control error [rad^2]", table1, ("signal", "statistic"))
    hg, vfe = (_pick(table1, "phi", "mean")[key] for key in ("HG", "VFE"))
    return lines + [
        f"Similar control accuracy (paper's point): mean phi^2 with HG / with VFE = {hg / vfe:.2f} "
        f"(target within a factor 2).",
        "",
    ]


def _table2_lines(table2: list[dict], sweep: list[dict]) -> list[str]:
    """Table II (squared velocity errors), the VFE's cut of them against the paper's, and the fairness sweep."""
    lines = _table_section("Table II: squared velocity error [(rad/s)^2]", table2, ("reference", "signal", "statistic"))
    for reference in ("butterworth", "true"):
        for signal, paper_cut in (("phi_dot", 31 / 9), ("theta_dot", 4.1 / 1.1)):
            row = _pick(table2, signal, "mean", reference)
            lines.append(
                f"- {signal} vs {reference}: VFE cuts the mean squared error {row['HG'] / row['VFE']:.1f}x "
                f"(paper {paper_cut:.1f}x)."
            )
    lines += [
        "",
        "Fair comparison (`observer_sweep.csv`, `observer_sweep.png`): each observer replayed on the "
        "pilot run's measurements over its tuning parameter; the lowest arm velocity error vs the "
        "true velocity is kept.",
        "",
        "| observer | parameter | value | phi_dot MSE vs true | phi_dot MSE vs Butterworth | chosen |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {row['observer'].upper()} | {row['parameter']} | {row['value']:g} | "
        f"{row['phi_dot_mse_true']:.3g} | {row['phi_dot_mse_butterworth']:.3g} | "
        f"{'yes' if row['best'] else ''} |"
        for row in sweep
    ]
    return lines + [""]


def _fig5_lines(fig5: dict) -> list[str]:
    """Fig. 5's steady friction estimates F_hat and F_hat + eps_hat_F (Eq. 8, 11) against the true friction."""
    lines = [
        "## Fig. 5: friction observed with two Dahl sets (no compensation, u = u_LQ) [N m]",
        "",
        "| set | direction | F_hat | F_hat + eps_hat_F | true | error of F_hat + eps_hat_F |",
        "|---|---|---|---|---|---|",
    ]
    for name, steady in fig5.items():
        for direction in ("pos", "neg"):
            value = steady[direction]
            error = abs(value["F_hat_plus_eps"] - value["true"]) / abs(value["true"])
            lines.append(
                f"| {name} | phi_dot {'>' if direction == 'pos' else '<'} 0 | {value['F_hat']:.4f} | "
                f"{value['F_hat_plus_eps']:.4f} | {value['true']:.4f} | {error:.1%} |"
            )
    return lines + [""]


def _adaptation_lines(a: dict) -> list[str]:
    """Figs. 6-7: the adapted K_sigma (Eq. 18) and friction against the true rig's, and the pendulum's excursion."""
    return [
        "## Figs. 6-7: K_sigma adaptation from Fc_hat = 0.009 N m, enabled at t = 7.8 s",
        "",
        "| quantity | simulation | target (paper / true rig) | ratio |",
        "|---|---|---|---|",
        _ratio_row("K_sigma+ (final)", a["K_sigma_plus"], reproduce.ARM_COULOMB_POS / reproduce.UNDERESTIMATED_COULOMB),
        _ratio_row(
            "K_sigma- (final)", a["K_sigma_minus"], reproduce.ARM_COULOMB_NEG / reproduce.UNDERESTIMATED_COULOMB
        ),
        _ratio_row("adapted F_hat, phi_dot > 0 [N m]", a["friction_pos"], -reproduce.ARM_COULOMB_POS),
        _ratio_row("adapted F_hat, phi_dot < 0 [N m]", a["friction_neg"], reproduce.ARM_COULOMB_NEG),
        f"| max abs(theta) [rad] | {a['theta_abs_max']:.4f} | < 0.1 | |",
        "",
        f"The paper reports K_sigma settling in {reproduce.PAPER_K_SIGMA_RANGE[0]:g}-"
        f"{reproduce.PAPER_K_SIGMA_RANGE[1]:g}.",
        "",
    ]


def _table_section(title: str, rows: list[dict], keys: tuple[str, ...]) -> list[str]:
    lines = [
        f"## {title}",
        "",
        "| " + " | ".join(keys) + " | HG | paper HG | ratio | VFE | paper VFE | ratio |",
        "|" + "---|" * (len(keys) + 6),
    ]
    for row in rows:
        cells = [str(row[key]) for key in keys]
        for name in ("HG", "VFE"):
            cells += [f"{row[name]:.3g}", f"{row['paper_' + name]:.3g}", f"{row[name] / row['paper_' + name]:.2f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines + [""]


def _pick(rows: list[dict], signal: str, statistic: str, reference: str | None = None) -> dict:
    return next(
        row
        for row in rows
        if row["signal"] == signal
        and row["statistic"] == statistic
        and (reference is None or row["reference"] == reference)
    )


def _ratio_row(label: str, value: float, target: float) -> str:
    return f"| {label} | {value:.4g} | {target:.4g} | {value / target:.2f} |"
