"""``python -m studies consistency nees|outliers|long-run|mrclam|association ...``: can we trust Σ?

One sub-command per study, each with only its own options:

- ``nees``: NEES/NIS over Monte Carlo runs against chi-square bands
  (`ekfslam.analysis.consistency`);
- ``outliers RATE``: the map error with and without the NIS gate when a share of the sightings
  are outliers (`studies.robustness.outlier_study`);
- ``long-run [--steps N]``: drive N steps and check Σ's smallest eigenvalue (`robustness.long_run`);
- ``mrclam [DATASET]``: pose NEES of every MRCLAM robot against Vicon
  (`ekfslam.analysis.mrclam_consistency`);
- ``association [--runs N]``: nn against jcbb with the ids hidden on the stress scenario, and a
  picture of the wrong associations (`ekfslam.analysis.association_stress`).

The Monte Carlo studies (nees, outliers, association) and the robots of ``mrclam`` run on every
local core by default; ``--jobs 1`` runs them in this process, ``--dask tcp://host:8786`` on a
Dask cluster (`ekfslam.analysis.parallel`). The numbers are the same for the same seeds whatever
the backend.
"""

from __future__ import annotations

import argparse
import dataclasses
import json

from ekfslam.analysis import association_stress
from ekfslam.analysis.consistency import (
    CONFIDENCE,
    Consistency,
    compare,
)
from ekfslam.analysis.mrclam_consistency import (
    NOISE_SETTINGS,
    mrclam_consistency,
    table,
)
from ekfslam.cli import args as ca
from ekfslam.cli.common import mrclam_folder
from ekfslam.core.filter.config import CHI2_2DOF_99, FilterConfig, FilterCounts
from ekfslam.core.filter.config import LINEARIZATIONS as ALL_LINEARIZATIONS
from ekfslam.files import save_figure
from ekfslam.logs.mrclam.defaults import MRCLAM_CONFIG
from ekfslam.logs.mrclam.load import ROBOTS
from ekfslam.sim.scenarios import SCENARIOS
from ekfslam.viz.association import plot_wrong_associations
from ekfslam.viz.consistency import plot_consistency, plot_mrclam_nees
from studies import robustness
from studies.cli.common import add_parallel_arguments


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``consistency`` and its studies (`help`: its line in `studies.__main__`)."""
    parser = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    studies = parser.add_subparsers(dest="study", required=True, parser_class=ca.Parser)

    p = studies.add_parser("nees", help="NEES/NIS over Monte Carlo runs against chi-square bands")
    _runs_and_trajectory(p)
    _linearization(p, "standard")
    _seed(p)
    _gate(p, off=True)
    p.add_argument(
        "--wheel-noise",
        type=ca.non_negative(10.0, why="rad/s"),
        help="override the scenario's wheel noise, rad/s",
    )
    _iterations(p)
    add_parallel_arguments(p)
    ca.add_json_argument(p)
    ca.add_plot_argument(p, "draw the averages and their bands to FILE")
    p.set_defaults(func=cmd_nees)

    p = studies.add_parser(
        "outliers", help="outlier gating: the map error with the gate on and off"
    )
    p.add_argument("rate", type=ca.probability(), help="the outlier rate, in [0, 1] (e.g. 0.05)")
    _runs_and_trajectory(p)
    _seed(p)
    _gate(p)
    p.add_argument(
        "--gate-after",
        type=ca.whole(1, 10**6),
        default=FilterConfig.gate_after,
        help="gate_after (default: the filter's, %(default)s)",
    )
    add_parallel_arguments(p)
    ca.add_json_argument(p)
    p.set_defaults(func=cmd_outliers)

    p = studies.add_parser("long-run", help="a long Σ run: its smallest eigenvalue, its symmetry")
    p.add_argument(
        "--steps",
        type=ca.whole(1, 10**7),
        default=100_000,
        help="steps to drive (default: %(default)s)",
    )
    _linearization(p, "standard")
    _seed(p)
    ca.add_json_argument(p)
    p.set_defaults(func=cmd_long_run)

    p = studies.add_parser("mrclam", help="pose NEES of the MRCLAM robots against Vicon")
    p.add_argument(
        "dataset",
        nargs="?",
        type=ca.mrclam_dataset,
        default=7,
        metavar="DATASET",
        help="a MRCLAM dataset: its folder or its number 1-9 (default: 7)",
    )
    p.add_argument(
        "--noise",
        choices=sorted(NOISE_SETTINGS),
        default="map",
        help="noise tuned for the map (MRCLAM_NOISE) or for consistency",
    )
    p.add_argument(
        "--robots",
        type=int,
        nargs="+",
        choices=ROBOTS,
        default=list(ROBOTS),
        help="which robots (default all five)",
    )
    _linearization(p, "both")
    _gate(p)
    add_parallel_arguments(p)
    ca.add_json_argument(
        p,
        "print one JSON object; keys: robots.<N>.<linearization>.{mean, median, "
        "fraction_in_interval, heading_mean, aligned_error, rejected, rows}, "
        "average.<linearization>.{same}, interval, ideal, confidence, noise_name, noise, "
        "dataset_dir, rows_used, plot",
    )
    ca.add_plot_argument(p, "draw each robot's pose NEES over time to FILE")
    p.set_defaults(func=cmd_mrclam)

    p = studies.add_parser(
        "association", help="nn against jcbb on the stress scenario (close tags, drift)"
    )
    p.add_argument(
        "--runs", type=ca.whole(1, 1000), default=1, help="simulated runs, 1 to 1000 (default 1)"
    )
    p.add_argument(
        "--seed",
        type=ca.seed(),
        default=2,
        help="seed of the first run (then +1, +2...; default 2)",
    )
    add_parallel_arguments(p)
    ca.add_json_argument(p)
    ca.add_plot_argument(p, "draw the first run's wrong associations to FILE")
    p.set_defaults(func=cmd_association)


def _runs_and_trajectory(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--runs",
        type=ca.whole(1, 10_000),
        default=50,
        help="Monte Carlo runs, 1 to 10000 (default 50)",
    )
    p.add_argument("--trajectory", choices=SCENARIOS, default="octagon", help="the scenario")


def _linearization(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument(
        "--linearization",
        choices=[*ALL_LINEARIZATIONS, "both", "all"],
        default=default,
        help="standard EKF, first-estimates Jacobian (fej), right-invariant EKF "
        "(invariant); both = standard and fej, all = the three "
        "(default: %(default)s)",
    )


def _iterations(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--iterations",
        type=ca.whole(1, 100),
        default=1,
        help="linearisations per update: 1 is the EKF, more the iterated EKF "
        "(standard and invariant; FEJ keeps 1; default: %(default)s)",
    )


def _seed(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--seed", type=ca.seed(), default=0, help="seed of the first run (then +1, +2...)"
    )


def _gate(p: argparse.ArgumentParser, off: bool = False) -> None:
    """--gate; off: the default is no gate (the outlier-free ``nees`` study, `STUDY_GATE`)."""
    if off:
        p.add_argument(
            "--gate",
            type=ca.non_negative(1e6),
            default=0.0,
            help=f"NIS gate; default off (0): the runs have no outliers, and a gate would drop "
            f"the largest true innovations (the filter's is {CHI2_2DOF_99:.2f})",
        )
        return
    p.add_argument(
        "--gate",
        type=ca.non_negative(1e6),
        default=CHI2_2DOF_99,
        help="NIS gate; 0 turns it off (%(default).2f)",
    )


def _linearizations(args: argparse.Namespace) -> tuple[str, ...]:
    choice = args.linearization
    return {"both": ("standard", "fej"), "all": ALL_LINEARIZATIONS}.get(choice, (choice,))


def _emit(args: argparse.Namespace, data: dict, text: str) -> None:
    print(json.dumps(data, indent=2, allow_nan=False) if args.json else text)


def cmd_nees(args: argparse.Namespace) -> int:
    lins = _linearizations(args)
    results = compare(
        args.trajectory,
        args.runs,
        lins,
        gate=None if args.gate == 0 else args.gate,
        first_seed=args.seed,
        wheel_noise_sigma=args.wheel_noise,
        iterations=args.iterations,
        jobs=args.jobs,
        dask=args.dask,
    )
    out = {r.linearization: r.as_dict() for r in results}
    if args.plot is not None:
        save_figure(plot_consistency(results), args.plot)
        for d in out.values():
            d["plot"] = str(args.plot)
    _emit(args, out if len(out) > 1 else out[lins[0]], "\n\n".join(map(nees_table, results)))
    return 0


def cmd_outliers(args: argparse.Namespace) -> int:
    gate = None if args.gate == 0 else args.gate
    study = robustness.outlier_study(
        args.trajectory,
        args.runs,
        args.rate,
        gate=gate or CHI2_2DOF_99,
        gate_after=args.gate_after,
        first_seed=args.seed,
        jobs=args.jobs,
        dask=args.dask,
    )
    lines = [
        f"outliers at {study.rate:.0%} on {study.scenario}, {study.runs} runs: aligned map "
        "error (eq. 17), mean over runs",
        f"{'case':<10}{'gate':>6}{'error (m)':>11}{'median':>9}{'x clean':>9}"
        f"{'injected':>10}{'rejected':>10}{'accepted':>10}",
    ]
    for c in study.cases:
        lines.append(
            f"{c.label:<10}{'on' if c.gate else 'off':>6}{c.map_error:>11.4f}"
            f"{c.map_error_median:>9.4f}{c.ratio:>9.2f}{c.injected:>10}{c.rejected:>10}"
            f"{c.accepted:>10}"
        )
    _emit(args, study.as_dict(), "\n".join(lines))
    return 0


def cmd_long_run(args: argparse.Namespace) -> int:
    lins = _linearizations(args)
    found = [robustness.long_run(args.steps, lin, seed=args.seed) for lin in lins]
    out = {r.linearization: dataclasses.asdict(r) | {"passed": r.passed} for r in found}
    for r in found:
        out[r.linearization]["counts"] = dataclasses.asdict(r.counts)
    text = "\n".join(
        f"{r.linearization}: {r.steps} steps, {r.landmarks} landmarks: smallest eigenvalue / "
        f"trace >= {r.min_eigenvalue_ratio:.3e} (step {r.worst_step}), asymmetry "
        f"{r.max_asymmetry:.1e}, finite {r.finite}: {'PASS' if r.passed else 'FAIL'} "
        f"({r.seconds:.1f} s)"
        for r in found
    )
    _emit(args, out if len(found) > 1 else out[lins[0]], text)
    return 0 if all(r.passed for r in found) else 1


def cmd_mrclam(args: argparse.Namespace) -> int:
    """The robot x linearization table, --json, --plot."""
    folder = mrclam_folder(args.dataset)
    lins = _linearizations(args)
    config = dataclasses.replace(MRCLAM_CONFIG, gate=None if args.gate == 0 else args.gate)
    study = mrclam_consistency(
        folder, args.noise, tuple(args.robots), lins, config, jobs=args.jobs, dask=args.dask
    )
    out = study.as_dict()
    if args.plot is not None:
        save_figure(plot_mrclam_nees(study), args.plot)
        out["plot"] = str(args.plot)
    print(
        json.dumps(out, indent=2, allow_nan=False) if args.json else table(study, out.get("plot"))
    )
    return 0


def cmd_association(args: argparse.Namespace) -> int:
    """known, nn and jcbb on the stress scenario: correct fraction and aligned error."""
    study = association_stress.stress_study(args.runs, args.seed, args.jobs, args.dask)
    out = study.as_dict()
    if args.plot is not None:
        out["plot"] = str(save_figure(plot_wrong_associations(study), args.plot))
    lines = [
        f"stress scenario (8 pairs of tags 0.3 m apart, 2 drifting laps), seeds "
        f"{study.seeds[0]}..{study.seeds[-1]}: mean over {len(study.seeds)} run(s)",
        f"{'method':<8}{'correct':>9}{'aligned error (m)':>19}{'wrong (first run)':>19}",
    ]
    for m in association_stress.METHODS:
        frac, err = study.mean(m, "correct_fraction"), study.mean(m, "aligned_error")
        lines.append(
            f"{m:<8}{'–' if frac is None else f'{frac:.1%}':>9}"
            f"{'–' if err is None else f'{err:.4f}':>19}{study.cases[m][0].wrong:>19}"
        )
    if "plot" in out:
        lines.append(f"figure written to {out['plot']}")
    _emit(args, out, "\n".join(lines))
    return 0


def nees_table(r: Consistency) -> str:
    """The text of ``consistency nees`` for one linearization: averages against their bands."""
    d = r.as_dict()
    lines = [
        f"{r.scenario}, {r.runs} runs, {r.linearization} linearization, "
        f"gate {'off' if r.gate is None else f'{r.gate:.2f}'}"
        f"{f', {r.iterations} iterations' if r.iterations > 1 else ''}: "
        f"averages over the runs and the {CONFIDENCE:.0%} chi-square band",
        f"{'':<16}{'mean':>8}{'max':>8}   {'band (median)':<16}{'steps in band':>14}",
    ]
    for key, label in (
        ("nees_pose", "pose NEES"),
        ("nees_pose_xi", "pose NEES in ξ"),
        ("nees_heading", "heading NEES"),
        ("nees_landmark", "landmark NEES"),
        ("nis", "NIS"),
    ):
        q = d[key]
        band = f"[{q['band'][0]:.2f}, {q['band'][1]:.2f}]"
        lines.append(
            f"{label:<16}{q['mean']:>8.2f}{q['max']:>8.2f}   {band:<16}"
            f"{q['fraction_in_band']:>13.1%}"
        )
    m = d["map_nees_final"]
    lines.append(
        f"final map NEES {m['mean']:.1f} ({m['dof']} dof, band [{m['band'][0]:.1f}, "
        f"{m['band'][1]:.1f}])"
    )
    lines.append(counts_line(r.counts))
    if "plot" in d:
        lines.append(f"figure written to {d['plot']}")
    return "\n".join(lines)


def counts_line(counts: FilterCounts) -> str:
    """The filters' counts over all runs, each number after its own label."""
    c = counts
    return (
        f"over all runs: {c.predictions} predictions; updates {c.accepted} accepted, "
        f"{c.rejected} rejected, {c.refused} refused; landmarks {c.initialised} initialised, "
        f"{c.reinitialised} re-initialised"
    )
