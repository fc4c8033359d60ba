"""The ``furuta-drake`` command line: ``simulate``, ``diagnose``, ``design``, ``tune``, ``reproduce``, ``sweep``.

Bad input ends with exit code 2 and one line naming the file, line or key; a run the monitor stopped ends with
exit code 3 and the time and cause; no traceback for either.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from furuta_drake.errors import ConfigError, FurutaError, SimulationDiverged

EXIT_BAD_INPUT = 2
EXIT_DIVERGED = 3


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except SimulationDiverged as err:
        print(f"furuta-drake {args.command}: {err}", file=sys.stderr)
        return EXIT_DIVERGED
    except FurutaError as err:
        print(f"furuta-drake {args.command}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"furuta-drake {args.command}: interrupted; no result was written", file=sys.stderr)
        return 130


def _simulate_parser(sub) -> None:
    """The ``simulate`` command's options."""
    sim = sub.add_parser("simulate", help="simulate a Furuta rig in closed loop and write its log")
    sim.add_argument("--config", type=Path, help="simulate config YAML (default: the Lund rig balancing)")
    sim.add_argument(
        "--rig",
        help="shipped rig name (lund, qube_servo2, geared) or a rig YAML (docs/diagnose.md); ignored with --config",
    )
    sim.add_argument("--duration", type=float, help="override the config's duration [s]")
    sim.add_argument("--seed", type=int, help="override the config's seed")
    sim.add_argument(
        "--velocity-source",
        choices=["true", "derivative", "hg", "vfe"],
        help="override the state estimate the LQR uses",
    )
    sim.add_argument("--out", type=Path, required=True, help="output directory")
    sim.add_argument("--force", action="store_true", help="replace a non-empty output directory")
    sim.add_argument("--meshcat", action="store_true", help="animate live in Meshcat")
    sim.add_argument("--html", type=Path, help="also save a self-contained Meshcat recording (HTML)")
    sim.set_defaults(run=_run_simulate)


def _diagnose_parser(sub) -> None:
    """The ``diagnose`` command's options."""
    diag = sub.add_parser("diagnose", help="diagnose the sim-to-real gap of a rig from its logs")
    diag.add_argument(
        "--rig",
        type=Path,
        required=True,
        help="rig YAML (docs/diagnose.md; `furuta-drake rig --template` writes one to start from)",
    )
    diag.add_argument("--train", type=Path, nargs="+", required=True, help="logs the candidates are fitted on")
    diag.add_argument("--heldout", type=Path, nargs="*", default=[], help="logs every held-out figure uses")
    diag.add_argument("--out", type=Path, required=True, help="output directory")
    diag.add_argument("--force", action="store_true", help="replace a non-empty output directory")
    diag.add_argument("--workers", type=int, help="processes for the candidate fits (default: all cores)")
    diag.add_argument(
        "--scheduler",
        help="address of an existing Dask scheduler whose workers run the fits and "
        "replays (same results as local processes)",
    )
    diag.add_argument(
        "--folds",
        type=int,
        help="repeat the decision on K >= 2 splits of the logs into train and "
        "held-out blocks and report its consistency",
    )
    diag.add_argument(
        "--columns",
        metavar="NAME=COLUMN,...",
        help="the logs' own column names, e.g. time=t,theta=alpha,phi=theta,voltage=vm (names: time, "
        "theta, phi, torque, voltage; a name not mapped is read as itself; in an MCAP log an "
        "unmapped time is each message's log time)",
    )
    diag.add_argument(
        "--angle-unit", help="unit of both logged angles: rad (default), deg or counts (the rig's counts_per_rev)"
    )
    diag.add_argument(
        "--topic",
        help="MCAP channel holding the run, JSON messages whose fields are the columns "
        "(default: the file's only channel); logs are CSV, Parquet or MCAP by extension",
    )
    diag.add_argument(
        "--run-column",
        metavar="NAME",
        help="a column (or MCAP field) numbering the runs of a file of many runs (a trial table): each run is "
        "a log of its own, named file.csv[run=7], and held-out data are whole runs",
    )
    diag.set_defaults(run=_run_diagnose)


def _from_diagnosis(sub, name: str, summary: str):
    """A command that reads a diagnosis: its parser with ``--diagnosis``, ``--out`` and ``--force``."""
    parser = sub.add_parser(name, help=summary)
    parser.add_argument("--diagnosis", type=Path, required=True, help="the --out directory of furuta-drake diagnose")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--force", action="store_true", help="replace a non-empty output directory")
    return parser


def _design_parser(sub) -> None:
    """The ``design`` command's options."""
    des = _from_diagnosis(sub, "design", "design the experiment that settles what a diagnosis could not decide")
    des.add_argument(
        "--duration",
        type=float,
        help="length of the experiment [s]; its first half trains, its second is held out (default: the "
        "shortest repeat of an 8 s experiment predicted to settle every pair, up to 64 s; when the design "
        "targets detection limits, the shortest of 8, 16 and 32 s predicted to bring them to their sizes, else the "
        "one bringing them lowest)",
    )
    mode = des.add_mutually_exclusive_group()
    mode.add_argument(
        "--hanging",
        dest="balancing",
        action="store_false",
        help="an open-loop command played from rest with the pendulum hanging (default, unless the design "
        "targets detection limits: then the mode of the experiment chosen by its predicted limits)",
    )
    mode.add_argument(
        "--balancing",
        dest="balancing",
        action="store_true",
        help="a dither added to the project's LQR balancing the pendulum upright",
    )
    des.add_argument(
        "--target",
        nargs="+",
        default=[],
        metavar="EFFECT=VALUE",
        help="separate the accepted model from it plus EFFECT at VALUE (its main parameter, as the "
        "report's detection_limits state it) instead of from its rivals; unmodelled_torque=SIZE: the "
        "diagnosis' unmodelled torque at an RMS of SIZE N m along its train logs",
    )
    des.add_argument(
        "--arm-bound",
        type=float,
        default=1.0,
        help="largest arm angle |phi| allowed under any hypothesis [rad] (default 1)",
    )
    des.add_argument("--seed", type=int, default=0, help="seed of the search and of the predicted noise (default 0)")
    des.set_defaults(run=_run_design, balancing=None)


def _tune_parser(sub) -> None:
    """The ``tune`` command's options."""
    tune = _from_diagnosis(sub, "tune", "design the rig's balancing controller on the model a diagnosis corrected")
    tune.add_argument(
        "--duration", type=float, default=10.0, help="length of each predicted balancing run [s] (default 10)"
    )
    tune.add_argument(
        "--seed", type=int, default=0, help="seed of the predicted runs' disturbance and encoder noise (default 0)"
    )
    tune.add_argument(
        "--draws",
        type=int,
        default=3,
        help="seeded draws of the rig's disturbance each prediction averages, when the diagnosis read one (default 3)",
    )
    tune.add_argument("--workers", type=int, help="processes for the predicted runs (default: all cores)")
    tune.add_argument(
        "--swingup",
        type=Path,
        help="a simulate config with controller.mode swingup: predict each design's catch time behind that swing-up",
    )
    tune.set_defaults(run=_run_tune)


def _rig_parser(sub) -> None:
    """The ``rig`` command's options."""
    rig = sub.add_parser("rig", help="write an annotated rig file to start from, or check one")
    rig_action = rig.add_mutually_exclusive_group(required=True)
    rig_action.add_argument(
        "--template",
        choices=["lund", "qube_servo2", "geared"],
        help="print the shipped rig's file with every key explained (redirect it to a file): the paper's Lund rig, "
        "the QUBE-Servo 2, or a geared lab-built rig (gearmotor, arm encoder, 100 Hz)",
    )
    rig_action.add_argument(
        "--check",
        type=Path,
        metavar="FILE",
        help="print the constants FILE implies: lumped constants, the paper's alpha1, alpha2, "
        "beta3-beta5, the upright poles, the hanging natural frequency and a drive's constants",
    )
    rig.set_defaults(run=_run_rig)


def _reproduce_parser(sub) -> None:
    """The ``reproduce`` command's options."""
    rep = sub.add_parser("reproduce", help="reproduce the paper's Tables I-II and Figs. 5-7 on the simulated Lund rig")
    rep.add_argument(
        "--only",
        nargs="+",
        metavar="EXPERIMENT",
        help="experiments to run among table1 table2 fig5 fig6 fig7 beyond real (default: the paper's, "
        "table1 ... fig7; beyond runs the studies of the paper's open problems, a few minutes; real "
        "runs the observers and the closed loop on the real QUBE-Servo 2 logs, before and after "
        "the diagnosis' correction, a few minutes)",
    )
    rep.add_argument("--seed", type=int, default=0, help="seed of the excitation and encoder noise (default 0)")
    rep.add_argument(
        "--table-duration",
        type=float,
        default=20.0,
        help="length of the runs of Tables I-II and Fig. 5 [s] (default 20, as the paper)",
    )
    rep.add_argument(
        "--adaptation-duration",
        type=float,
        default=40.0,
        help="length of the run of Figs. 6-7 [s] (default 40; adaptation starts at 7.8 s)",
    )
    rep.add_argument(
        "--quick",
        action="store_true",
        help="short runs everywhere (4 s tables, 12 s adaptation, short studies): a smoke test",
    )
    rep.add_argument("--out", type=Path, required=True, help="output directory")
    rep.add_argument("--force", action="store_true", help="replace a non-empty output directory")
    rep.set_defaults(run=_run_reproduce)


def _sweep_parser(sub) -> None:
    """The ``sweep`` command's options."""
    sweep = sub.add_parser("sweep", help="simulate a grid or random sample of configs on Dask, write a CSV of metrics")
    sweep.add_argument("--config", type=Path, required=True, help="sweep YAML (see furuta_drake.sweep)")
    sweep.add_argument("--out", type=Path, required=True, help="output directory")
    sweep.add_argument("--force", action="store_true", help="replace a non-empty output directory")
    sweep.add_argument("--scheduler", help="address of an existing Dask scheduler (default: a local cluster)")
    sweep.add_argument("--workers", type=int, help="worker processes of the local cluster (default: one per core)")
    sweep.set_defaults(run=_run_sweep)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="furuta-drake", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (
        _simulate_parser,
        _diagnose_parser,
        _design_parser,
        _tune_parser,
        _rig_parser,
        _reproduce_parser,
        _sweep_parser,
    ):
        add(sub)
    return parser


def _simulate_config(args):
    from furuta_drake.config import SimulationConfig, load_config

    if args.config is not None:
        config = load_config(args.config)
    elif args.rig is None or args.rig in ("lund", "qube_servo2", "geared"):
        config = SimulationConfig.from_rig(args.rig or "lund")
    else:
        from furuta_drake.effects.corrected import rig_config
        from furuta_drake.rig_file import load_rig

        config = rig_config(load_rig(args.rig))
    overrides = {}
    if args.duration is not None:
        overrides["duration"] = args.duration
    if args.seed is not None:
        overrides["seed"] = args.seed
    if args.velocity_source is not None:
        overrides["controller"] = dataclasses.replace(config.controller, velocity_source=args.velocity_source)
    config = dataclasses.replace(config, **overrides)
    config.validate()
    return config


def _run_simulate(args) -> int:
    from furuta_drake.outputs import atomic_output_dir
    from furuta_drake.plotting import plot_states
    from furuta_drake.results import config_yaml_with_provenance, summary, write_json, write_log_csv
    from furuta_drake.simulate import simulate

    config = _simulate_config(args)
    if args.html is not None:
        _check_html_path(args.html, args.force)
    meshcat = _start_meshcat() if (args.meshcat or args.html is not None) else None
    with atomic_output_dir(args.out, force=args.force) as out:
        progress = _Progress(config.duration, "simulate")
        if meshcat is not None:
            meshcat.StartRecording()
        try:
            result = simulate(config, meshcat=meshcat, progress=progress.update_to)
        except ConfigError as err:  # found while building the diagram (e.g. a gain that does not stabilise)
            if args.config is None:
                raise
            from furuta_drake.yamlio import locate_in_file

            raise locate_in_file(args.config, err) from None
        finally:
            progress.close()
        write_log_csv(result, out / "log.csv")
        (out / "config.yaml").write_text(config_yaml_with_provenance(config))
        write_json(out / "summary.json", summary(result, config))
        plot_states(result, out / "states.png")
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        if args.html is not None:
            staging = args.html.with_name(f".{args.html.name}.partial")
            staging.write_text(meshcat.StaticHtml())
            staging.replace(args.html)
    rate = config.duration / result.wall_time if result.wall_time > 0 else float("inf")
    print(
        f"simulated {config.duration:g} s in {result.wall_time:.2f} s ({rate:.1f}x real time); "
        f"max |theta| = {abs(result.state[:, 0]).max():.4f} rad; wrote {args.out}"
    )
    return 0


def _check_html_path(path: Path, force: bool) -> None:
    """Refuse an ``--html`` path that cannot take the recording, before the run."""
    if path.is_dir():
        raise ConfigError(f"{path}: is a directory, expected the path of an HTML file (--html)")
    if path.exists() and not force:
        raise ConfigError(f"{path}: exists; pass --force to overwrite it")
    if not path.parent.is_dir():
        raise ConfigError(f"{path}: cannot write the recording there, {path.parent} is not a directory")


def _run_reproduce(args) -> int:
    from tqdm import tqdm

    from furuta_drake.paper.report import (
        BEYOND_STUDIES,
        PAPER_EXPERIMENTS,
        ReproductionSettings,
        run_reproduction,
    )
    from furuta_drake.real_rig.report import reproduce_real

    quick = (
        {"table_duration": 4.0, "adaptation_duration": 12.0, "small_beyond": True, "small_real": True}
        if args.quick
        else {"table_duration": args.table_duration, "adaptation_duration": args.adaptation_duration}
    )
    settings = ReproductionSettings(only=args.only or list(PAPER_EXPERIMENTS), seed=args.seed, **quick)
    settings.validate()
    only = set(settings.only)
    steps = (
        4 * bool(only & {"table1", "table2"})
        + 2 * ("fig5" in only)
        + bool(only & {"fig6", "fig7"})
        + len(BEYOND_STUDIES) * ("beyond" in only)
        + 20 * ("real" in only)
    )
    with tqdm(total=steps, desc="reproduce", unit="run", disable=not sys.stderr.isatty()) as bar:
        figures = run_reproduction(
            settings,
            args.out,
            force=args.force,
            progress=lambda message: (bar.set_postfix_str(message), bar.update(1)),
            real=reproduce_real,
        )
    print(f"reproduced {', '.join(settings.only)} in {figures['wall_time_s']:.0f} s; see {args.out / 'report.md'}")
    return 0


def _run_sweep(args) -> int:
    import time

    from tqdm import tqdm

    from furuta_drake.sweep import load_sweep, run_sweep

    sweep = load_sweep(args.config)
    bar = tqdm(total=len(sweep.points), desc="sweep", unit="point", disable=not sys.stderr.isatty())
    start = time.perf_counter()
    try:
        rows = run_sweep(
            sweep,
            args.out,
            force=args.force,
            scheduler=args.scheduler,
            workers=args.workers,
            progress=lambda done, total: bar.update(done - bar.n),
        )
    finally:
        bar.close()
    diverged = sum(row["diverged"] for row in rows)
    print(f"swept {len(rows)} points ({diverged} diverged) in {time.perf_counter() - start:.1f} s; wrote {args.out}")
    return 0


def _run_rig(args) -> int:
    from furuta_drake.rig import RIGS
    from furuta_drake.rig_file import format_rig_check, rig_template

    if args.template is not None:
        print(rig_template(RIGS[args.template](), f"the shipped {args.template} rig"), end="")
    else:
        from furuta_drake.rig_file import load_rig

        print(format_rig_check(load_rig(args.check), str(args.check)), end="")
    return 0


def _run_diagnose(args) -> int:
    from tqdm import tqdm

    from furuta_drake.diagnosis.logs.format import LogFormat
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import write_report
    from furuta_drake.outputs import prepare_output_dir

    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {args.workers}")
    if args.workers is not None and args.scheduler is not None:
        raise ConfigError("--workers sizes the local processes; with --scheduler the cluster's workers run the fits")
    if args.folds is not None and args.folds < 2:
        raise ConfigError(f"--folds must be >= 2, got {args.folds}")
    log_format = LogFormat.parse(args.columns, args.angle_unit, args.topic, args.run_column)
    protect = [args.rig, *args.train, *args.heldout]
    prepare_output_dir(args.out, force=args.force, protect=protect)
    with tqdm(desc="fitting candidates", unit="fit", disable=not sys.stderr.isatty()) as bar:
        diagnosis = diagnose(
            rig=args.rig,
            train=args.train,
            heldout=args.heldout,
            folds=args.folds,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=lambda result: bar.update(1),
            log_format=log_format,
        )
    for note in diagnosis.notes:
        print(note)
    write_report(args.out, diagnosis, force=args.force, protect=protect)
    print(diagnosis_summary(diagnosis, args.out))
    return 0


def diagnosis_summary(diagnosis, out) -> str:
    """The line ``diagnose`` ends on: the verdict, the held-out gap before and after, the failed candidates' count
    (a candidate its step's screen left behind did not fail) and where the report is."""
    gap = diagnosis.gap
    failed = diagnosis.failed
    return (
        f"verdict: {diagnosis.verdict} (effects: {', '.join(diagnosis.effects) or '-'}); held-out gap "
        f"{gap.nominal['heldout']:.3g} -> {gap.with_effects['heldout']:.3g} counts "
        f"({gap.heldout_reduction:.0%} reduction)"
        + (f"; {len(failed)} candidate(s) failed, listed in the report" if failed else "")
        + f"; report in {out}"
    )


def _run_design(args) -> int:
    from furuta_drake.design.output import write_design
    from furuta_drake.design.pipeline import DesignSettings, design_experiment
    from furuta_drake.outputs import prepare_output_dir

    prepare_output_dir(args.out, force=args.force, protect=[args.diagnosis])
    settings = dataclasses.replace(DesignSettings(), seed=args.seed)
    design = design_experiment(
        args.diagnosis,
        duration=args.duration,
        balancing=args.balancing,
        targets=args.target,
        arm_bound=args.arm_bound,
        settings=settings,
        progress=lambda line: print(line, file=sys.stderr) if sys.stderr.isatty() else None,
    )
    for note in design.notes:
        print(note)
    write_design(args.out, design, force=args.force)
    if design.status != "design":
        print(f"no experiment: {design.reason}; wrote {args.out}")
        return 0
    weakest = min(pair["detection_probability"] for pair in design.pairs)
    print(
        f"designed a {design.duration:g} s experiment separating {len(design.pairs)} pair(s) of hypotheses "
        f"(weakest predicted detection probability {weakest:.0%}); play {args.out / 'experiment.csv'}"
    )
    return 0


def _run_tune(args) -> int:
    from furuta_drake.outputs import prepare_output_dir
    from furuta_drake.tune.output import write_tune
    from furuta_drake.tune.pipeline import TuneSettings, tune
    from furuta_drake.tune.swingup import read_swingup

    swingup = read_swingup(args.swingup) if args.swingup is not None else None
    settings = dataclasses.replace(
        TuneSettings(),
        duration=args.duration,
        seed=args.seed,
        draws=args.draws,
        workers=args.workers,
        swingup=swingup,
    )
    settings.validate()
    prepare_output_dir(args.out, force=args.force, protect=[args.diagnosis])
    tuning = tune(
        args.diagnosis,
        settings,
        progress=lambda line: print(line, file=sys.stderr) if sys.stderr.isatty() else None,
    )
    write_tune(args.out, tuning, force=args.force)
    before, after = tuning.nominal.prediction.figures, tuning.tuned.prediction.figures
    label, worst = tuning.tuned.worst_corner()
    change = (
        f"theta RMS {1e3 * before['theta_rms']:.3g} -> {1e3 * after['theta_rms']:.3g} mrad, limit cycle "
        f"{1e3 * before['limit_cycle_amplitude']:.3g} -> {1e3 * after['limit_cycle_amplitude']:.3g} mrad"
        if before is not None
        else f"the nominal design falls on the corrected model; tuned theta RMS {1e3 * after['theta_rms']:.3g} mrad"
    )
    kept = " (the nominal design kept: no design of the family predicts better)" if tuning.tuned.member is None else ""
    print(
        f"tuned{kept}: {change}; worst margins over the intervals {worst.gain_db:.3g} dB, "
        f"{1e3 * worst.delay_s:.3g} ms; wrote {args.out} (simulate --config {args.out / 'controller.yaml'})"
    )
    return 0


def _start_meshcat():
    from pydrake.geometry import StartMeshcat

    return StartMeshcat()


class _Progress:
    """A tqdm bar over simulated seconds (silent when stderr is not a terminal)."""

    def __init__(self, total: float, label: str):
        from tqdm import tqdm

        self.bar = tqdm(
            total=round(total, 3),
            desc=label,
            unit="sim s",
            disable=not sys.stderr.isatty(),
            bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} sim s [{elapsed}<{remaining}]",
        )

    def update_to(self, t: float) -> None:
        self.bar.update(round(t, 3) - self.bar.n)

    def close(self) -> None:
        self.bar.close()


if __name__ == "__main__":
    sys.exit(main())
