"""Subcommand ``gap``: the model-gap workflow (spec sections 1 and 4). Parsing and printing only;
the work is in `gyrodenoise.modelgap`."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gyrodenoise._extras import require
from gyrodenoise.cli.options import add_recording_options
from gyrodenoise.cli.program import emit_json
from gyrodenoise.console import log
from gyrodenoise.errors import InputError
from gyrodenoise.units import RATE_TO_DEG_S, TERM_BY_SYMBOL

if TYPE_CHECKING:
    import numpy as np

    from gyrodenoise.modelgap.curve import AllanCurve
    from gyrodenoise.modelgap.workflow import GapResult
    from gyrodenoise.simulator import ModelCard

TO_N = TERM_BY_SYMBOL["N"].to_spec     # white rate noise: sqrt(s-based variance density) -> N (deg/sqrt(h))


def register_cli(subparsers: Any) -> None:
    """Add the subcommand ``gap`` to the parser's ``subparsers``."""
    p = subparsers.add_parser(
        "gap", help="what a model card misses to behave like a measured record; writes the completed card",
        description="Simulate CARD like MEASURED (same rate and length, several seeds), compare Allan "
                    "deviation, PSD, mean and trend, name and fit the missing effects, write NEW.toml.")
    # IN is optional with --allan (a published curve is the measurement); the rate unit not
    # given is said in a note (a rad/s record read as deg/s fits 57x off)
    add_recording_options(p, input_optional=True, rate_unit_default=None,
                          input_help="recording CSV (columns time,rate; .gz ok) or a PSINS .imu log; omit with --allan")
    p.add_argument("--allan", default=None, metavar="CURVE.csv",
                   help="a published Allan curve (tau_s, allan_deviation[, adev_lci, adev_uci]) as the "
                        "measurement instead of IN; see docs/bench/gap.md")
    p.add_argument("--allan-unit", default=None,
                   help=f"unit of the curve's ADEV columns: {', '.join(RATE_TO_DEG_S)} (required with --allan: "
                        "a curve file carries no unit)")
    p.add_argument("--sensor", default=None, help="--allan: the rows of this sensor (file with a sensor column)")
    p.add_argument("--channel", default=None, help="--allan: the rows of this channel")
    p.add_argument("--n-samples", type=int, default=None, help="--allan: length of the published record "
                                                                "(when the file has no n_samples column)")
    p.add_argument("--latitude", type=float, default=None, metavar="DEG",
                   help="where the record was taken: a fitted bias is compared with the Earth's rotation")
    p.add_argument("--stop-band", action="append", default=None, metavar="LO:HI",
                   help="take LO-HI Hz out of the comparison (repeatable; default: spectral bumps found "
                        "automatically); 'none' for no band-stop")
    p.add_argument("--outliers", action="store_true",
                   help="replace isolated wild samples (> 10 robust sigmas off the running median, at most 1 %% "
                        "of the record) before the comparison, and name them")
    p.add_argument("--model", required=True, metavar="CARD.toml", help="model card (path or embedded name)")
    p.add_argument("--out", required=True, metavar="NEW.toml", help="completed card to write")
    p.add_argument("--seeds", type=int, default=6, help="simulated records per card (default 6, at least 3)")
    p.add_argument("--engine", default="native", choices=["fmu", "native"],
                   help="simulator: the core simulator (default, the fastest) or SimulatedFog.fmu through fmpy "
                        "(the same card: the two are bit-identical, tests/fmu/test_build_and_run.py)")
    p.add_argument("--fmu-dir", default=None, help="folder of SimulatedFog.fmu (default build/; built when missing "
                                                   "or stale)")
    p.add_argument("--workers", type=int, default=None, help="processes for the FMU engine, a whole number >= 1 (default: one per seed, "
                        "at most the number of cores); ignored by --engine native")
    p.add_argument("--max-effects", type=int, default=6, help="most steps that add or re-fit effects (default 6; "
                                                                "a joint re-fit of all noise terms is one step)")
    p.add_argument("--plot", default=None, metavar="PNG", help="figure (default: NEW.gap.png next to --out)")
    p.add_argument("--no-plot", action="store_true", help="write no figure")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_gap)


def _check_writable(path: str, what: str) -> None:
    d = Path(path).resolve().parent
    if Path(path).is_dir():
        raise InputError(f"{what} is a directory", str(path))
    if not d.is_dir() or not os.access(d, os.W_OK):
        raise InputError(f"cannot write {what}: folder {d} does not exist or is not writable", str(path))


def _stop_bands(values: Sequence[str] | None) -> str | list[tuple[float, float]] | None:
    if values is None:
        return "auto"
    if values == ["none"]:
        return None
    out: list[tuple[float, float]] = []
    for v in values:
        try:
            lo, hi = (float(x) for x in v.split(":"))
        except ValueError:
            raise InputError(f"--stop-band {v!r}: expected LO:HI in Hz (e.g. 1.5:3.5) or none") from None
        if not 0 <= lo < hi:
            raise InputError(f"--stop-band {v!r}: need 0 <= LO < HI")
        out.append((lo, hi))
    return out


def _at_fitted_rate(text: str, fs: float, card_hz: float, model: str) -> str:
    """The completed card stating the rate its terms were fitted at (the record's, ``fs``): a
    term fitted at one rate simulates differently at another (an angle Gauss-Markov tau of
    half a sample, white noise per sample). InputError (one line) when the card's rate
    cannot be rewritten (``sample_rate_hz`` not on a line of its own)."""
    from gyrodenoise.modelgap.cards import text_at_rate
    from gyrodenoise.simulator import parse_card
    at_rate = text_at_rate(text, fs)
    if parse_card(at_rate, str(model)).sample_rate_hz != float(fs):
        raise InputError(f"sensor.sample_rate_hz {card_hz:g} Hz: the terms were fitted at the record's "
                         f"{fs:g} Hz and the rate cannot be rewritten (put sample_rate_hz on a line of "
                         f"its own, or give a card at {fs:g} Hz)", str(model))
    return at_rate.rstrip("\n") + (f"\n# sample_rate_hz: {fs:g} Hz, the record's: the terms were fitted at it "
                                   f"(the input card said {card_hz:g} Hz)\n")


def _read_input(args: argparse.Namespace) -> tuple[np.ndarray, float, np.ndarray | None]:
    """The record: a PSINS .imu log (--rate-column gyro_x/y/z) or a recording CSV."""
    if str(args.input).lower().endswith(".imu"):
        from gyrodenoise.io.psins import read_psins
        imu = read_psins(args.input)
        rate = imu.axis("gyro_z" if args.rate_column == "rate" else args.rate_column)   # refuse first
        if args.latitude is None:
            args.latitude = imu.latitude_deg
            log(f"gyrodenoise: note: {args.input}: latitude {imu.latitude_deg:g} deg from the log's header")
        return rate, imu.sample_rate_hz, None
    from gyrodenoise.io.recording import read_recording
    rec = read_recording(args.input, rate_column=args.rate_column, time_column=args.time_column,
                         rate_unit=args.rate_unit, sample_rate_hz=args.sample_rate, time_unit=args.time_unit,
                         rate_scale=args.rate_scale, skip_rows=args.skip_rows,
                         spike_advice="gap --outliers replaces isolated samples more than 10 robust sigmas "
                                      "off the running median (another test: its count may differ)")
    from gyrodenoise.modelgap import check_record
    check_record(rec.rate_deg_s, args.input)
    args.input_notes = rec.notes     # said after every refusal (_rate_notes), and in the --json object
    return rec.rate_deg_s, rec.sample_rate_hz, rec.restarts


def _cmd_allan(args: argparse.Namespace, card: ModelCard) -> int:
    """gap --allan CURVE.csv: fit the card's noise terms to a published Allan curve, check by simulation."""
    from gyrodenoise.modelgap.cards import text_at_rate
    from gyrodenoise.modelgap.curve import card_from_terms, fit_curve, simulated_curve
    curve = _read_curve(args)
    terms, model = fit_curve(curve)
    text = card_from_terms(card.text, terms, f"fitted to {Path(args.allan).name} ({curve.label})", card.source)
    text = text_at_rate(text, curve.sample_rate_hz)
    log(f"gyrodenoise: simulating {args.seeds} records of {curve.n_samples} samples at {curve.sample_rate_hz:g} Hz")
    mean, _runs = simulated_curve(text, curve, range(1, args.seeds + 1), card.source)
    rows = _curve_rows(curve, model, mean)
    out_tau = [r["tau_s"] for r in rows if not r["inside"]]
    verdict = ("the simulated curve (mean of %d seeds) is inside the published bounds at every tau" % args.seeds
               if not out_tau else
               f"outside the published bounds at tau {', '.join(f'{t:g}' for t in out_tau)} s")
    text = _white_noise_notes(text, terms, curve)
    text = text.rstrip("\n") + (f"\n# noise terms fitted by gyrodenoise gap --allan to {Path(args.allan).name} "
                                f"({curve.label}, ADEV in {curve.unit}, {curve.n_samples} samples at "
                                f"{curve.sample_rate_hz:g} Hz); {verdict}\n")
    plot = _plot_path(args)
    if plot:
        from gyrodenoise.modelgap.report import plot_curve
        plot_curve(curve, model, mean, plot, title=f"{curve.label} ({Path(args.allan).name}) vs the fitted card")
    return _write_card(args, text, "\n".join(_curve_table(args, curve, rows) + [verdict]), plot,
                       {"allan": str(args.allan), "label": curve.label, "unit": curve.unit, "out": str(args.out),
                        "inside_every_tau": not out_tau, "points": rows})


def _read_curve(args: argparse.Namespace) -> AllanCurve:
    """The published Allan curve of --allan, in deg/s; InputError when --allan-unit is missing."""
    from gyrodenoise.modelgap.curve import read_allan_curve
    curve = read_allan_curve(args.allan, args.sensor, args.channel, args.allan_unit or "deg/s", args.sample_rate,
                             args.n_samples)
    if args.allan_unit is None:  # the file read well; its numbers mean nothing without their unit
        raise InputError(f"the curve's ADEV columns carry no unit: give --allan-unit {', '.join(RATE_TO_DEG_S)} "
                         "(a rad/s curve read as deg/s would be 57x too small)", args.allan)
    for note in curve.notes:
        log(f"gyrodenoise: note: {args.allan}: {note}")
    return curve


def _curve_rows(curve: AllanCurve, model: np.ndarray, mean: np.ndarray) -> list[dict[str, Any]]:
    """Per tau: the published ADEV and bounds (None where open), the fit, the simulated mean, inside?"""
    import numpy as np

    from gyrodenoise.modelgap.curve import inside
    ok = inside(curve, mean)
    return [{"tau_s": float(t), "adev_deg_s": float(a), "lo": None if not np.isfinite(lo) else float(lo),
             "hi": None if not np.isfinite(hi) else float(hi), "model": float(m_), "simulated": float(s_),
             "inside": bool(k)} for t, a, lo, hi, m_, s_, k in
            zip(curve.tau_s, curve.adev_deg_s, curve.lo_deg_s, curve.hi_deg_s, model, mean, ok)]


def _white_noise_notes(text: str, terms: Mapping[str, Any], curve: AllanCurve) -> str:
    """The card's comments on the fitted terms that act as white noise at the curve's rate."""
    fast = [(s_, t_) for s_, t_ in terms["gauss_markov"] if t_ < 2.0 / curve.sample_rate_hz]
    if fast:    # Gauss-Markov terms shorter than 2 samples act as (slightly coloured) white noise
        n_eq = math.sqrt(terms["angle_random_walk"] + sum(2.0 * s_ * s_ * t_ for s_, t_ in fast)) * TO_N
        text = text.rstrip("\n") + (f"\n# white noise: the Gauss-Markov terms with tau < 2 samples act as white "
                                    f"noise (the fit used their slight colour at the shortest taus); with N they "
                                    f"make an angle random walk of {n_eq:.4g} deg/sqrt(h)\n")
    if terms.get("angle_gauss_markov"):     # white rate noise below their tau, white angle noise above
        from gyrodenoise.modelgap.spectral import card_allan_variance
        from gyrodenoise.simulator import parse_card
        ad1 = math.sqrt(card_allan_variance(parse_card(text), [round(curve.sample_rate_hz)], curve.sample_rate_hz)[0])
        text = text.rstrip("\n") + (f"\n# the angle Gauss-Markov terms act as white rate noise below their tau "
                                    f"(N^2 = 2 sigma^2 / tau) and as white angle noise above; the whole card's "
                                    f"ADEV at 1 s is {ad1 * 3600:.4g} deg/h, read as an angle random walk "
                                    f"{ad1 * TO_N:.4g} deg/sqrt(h)\n")
    return text


def _curve_table(args: argparse.Namespace, curve: AllanCurve, rows: list[dict[str, Any]]) -> list[str]:
    """The lines of the published / fitted / simulated table, in deg/h."""
    lines = [f"gyrodenoise gap --allan: {args.allan} ({curve.label}; {len(curve.tau_s)} taus "
             f"{curve.tau_s[0]:g}-{curve.tau_s[-1]:g} s; ADEV in {curve.unit}"
             f"{'' if curve.unit == 'deg/s' else ', converted to deg/s'})",
             "tau_s      published_deg_h   bounds_deg_h            fit_deg_h   simulated_deg_h  inside"]
    for r in rows:
        b = (f"{r['lo'] * 3600 if r['lo'] else float('nan'):.4g}-{r['hi'] * 3600 if r['hi'] else float('nan'):.4g}")
        lines.append(f"{r['tau_s']:<10.4g} {r['adev_deg_s'] * 3600:<17.4g} {b:<23} {r['model'] * 3600:<11.4g} "
                     f"{r['simulated'] * 3600:<16.4g} {'yes' if r['inside'] else 'NO'}")
    return lines


def _plot_path(args: argparse.Namespace) -> str | None:
    """The figure to write: --plot, else NEW.gap.png beside --out; None with --no-plot."""
    return None if args.no_plot else (args.plot or str(Path(args.out).with_suffix("")) + ".gap.png")


def _write_card(args: argparse.Namespace, text: str, report: str, plot: str | None, obj: Any) -> int:
    """Write the completed card (last: only after a successful run), then the report: on stdout,
    or with --json on stderr and ``obj`` as the one JSON object on stdout."""
    try:
        Path(args.out).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", args.out) from None
    if args.json:
        print(report, file=sys.stderr)
        emit_json(obj)
    else:
        print(report)
        print(f"wrote {args.out}" + (f" and {plot}" if plot else ""))
    return 0


def _check_options(args: argparse.Namespace) -> None:
    """--seeds, --workers, --max-effects, one --rate-column, and that --out and --plot can be written."""
    if "," in str(args.rate_column):
        raise InputError(f"--rate-column {args.rate_column}: gap fits a model card to one sensor axis; run it "
                         f"once per column (--rate-column {args.rate_column.split(',')[0].strip()}, ...), each "
                         f"with its own --out")
    if args.seeds < 3:
        raise InputError(f"--seeds must be at least 3, got {args.seeds}")
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be at least 1 (omit it for one per seed up to the cores), "
                         f"got {args.workers}")
    if args.max_effects < 0:
        raise InputError(f"--max-effects must be >= 0, got {args.max_effects}")
    _check_writable(args.out, "--out")
    if args.plot and not args.no_plot:
        _check_writable(args.plot, "--plot")
    if not args.no_plot:
        require("report", "matplotlib", what="gyrodenoise gap's figure (or --no-plot)")
    if args.allan is None and args.engine == "fmu":     # --allan simulates with the core
        require("fmu", "fmpy", "pythonfmu", what="gyrodenoise gap --engine fmu (or --engine native, the default)")


def cmd_gap(args: argparse.Namespace) -> int:
    """``gyrodenoise gap``: a record (IN) or a published Allan curve (--allan) against a card."""
    from gyrodenoise.simulator import load_card
    card = load_card(args.model)
    _check_options(args)
    if args.allan is not None:
        if args.input is not None:
            raise InputError("give either IN (a record) or --allan CURVE.csv, not both", args.input)
        return _cmd_allan(args, card)
    if args.input is None:
        raise InputError("no measurement: give IN (a record) or --allan CURVE.csv")
    return _cmd_record(args, card)


def _cmd_record(args: argparse.Namespace, card: ModelCard) -> int:
    """gap IN: simulate the card like the record, name and fit what it misses, write the completed card."""
    from gyrodenoise.modelgap import check_record, format_report, gap, plot_gap
    plot = _plot_path(args)
    if plot:
        _check_writable(plot, "--plot")
    bands = _stop_bands(args.stop_band)
    rate, fs, restarts = _read_input(args)
    check_record(rate, args.input)
    _rate_notes(args, card, fs)
    res = gap(rate, fs, card, seeds=args.seeds, engine=args.engine,
              restarts=restarts, max_effects=args.max_effects, fmu_dir=args.fmu_dir,
              workers=args.workers, source=args.input, quiet=False, stop_bands=bands,
              latitude_deg=args.latitude, outliers=args.outliers)
    text = _completed_text(args, card, fs, res)
    # everything that can fail first; NEW.toml is written last, only after a successful run
    report = format_report(res, args.input)
    d = res.to_json()
    d.update({"out": str(args.out), "plot": plot, "source": str(args.input), "model": str(args.model),
              "notes": list(getattr(args, "input_notes", []))})
    if plot:
        plot_gap(res, plot, title=f"{Path(args.input).name} vs {Path(str(args.model)).name}")
    return _write_card(args, text, report, plot, d)


def _rate_notes(args: argparse.Namespace, card: ModelCard, fs: float) -> None:
    """Notes (after every refusal) on a card at another rate than the record, and on a unit not given."""
    from gyrodenoise.modelgap import card_at_rate
    if abs(card.sample_rate_hz - fs) > 1e-6 * fs:
        card_at_rate(card.text, fs, card.source)   # refuse first (one line), then note
        _at_fitted_rate(card.text, fs, card.sample_rate_hz, args.model)
        log(f"gyrodenoise: note: {args.model} says {card.sample_rate_hz:g} Hz, {args.input} is "
            f"{fs:g} Hz: simulating at the record's rate; {args.out} states the record's rate when a "
            f"term is fitted (the terms are fitted at it), else keeps the card's")
    for note in getattr(args, "input_notes", []):      # the reader's, after every refusal
        log(f"gyrodenoise: note: {args.input}: {note}")
    if args.rate_unit is None and not str(args.input).lower().endswith(".imu"):   # after every refusal
        log(f"gyrodenoise: note: {args.input}: column {args.rate_column!r} read as deg/s (the default; "
            f"--rate-unit deg/h or rad/s if the record is in another unit: the fitted card scales with it)")


def _completed_text(args: argparse.Namespace, card: ModelCard, fs: float, res: GapResult) -> str:
    """The completed card: at the record's rate when a term was fitted, with a comment on the edits."""
    from gyrodenoise.modelgap.report import describe_edits
    text = res.card_text
    if res.effects_added and abs(card.sample_rate_hz - fs) > 1e-6 * fs:
        text = _at_fitted_rate(text, fs, card.sample_rate_hz, args.model)
    if res.effects_added:
        text = text.rstrip("\n") + f"\n# completed by gyrodenoise gap from {Path(args.input).name}: " + \
            describe_edits(res.effects_added) + f"; gap {res.gap_before:.3g} -> {res.gap_after:.3g}\n"
    return text
