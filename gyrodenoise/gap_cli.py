"""Subcommand ``gap``: the model-gap workflow (spec sections 1 and 4). Parsing and printing only;
the work is in :mod:`gyrodenoise.modelgap`."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .errors import InputError


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def register_cli(subparsers):
    from .commands import _add_input_options
    p = subparsers.add_parser(
        "gap", help="what a model card misses to behave like a measured record; writes the completed card",
        description="Simulate CARD like MEASURED (same rate and length, several seeds), compare Allan "
                    "deviation, PSD, mean and trend, name and fit the missing effects, write NEW.toml.")
    _add_input_options(p)
    p.add_argument("--model", required=True, metavar="CARD.toml", help="model card (path or embedded name)")
    p.add_argument("--out", required=True, metavar="NEW.toml", help="completed card to write")
    p.add_argument("--seeds", type=int, default=6, help="simulated records per card (default 6, at least 3)")
    p.add_argument("--engine", default="fmu", choices=["fmu", "native"],
                   help="simulator: SimulatedFog.fmu through fmpy (default) or the core simulator (fast)")
    p.add_argument("--fmu-dir", default=None, help="folder of SimulatedFog.fmu (default build/; built when missing "
                                                   "or stale)")
    p.add_argument("--workers", type=int, default=None, help="processes for the FMU engine, a whole number >= 1 (default: one per seed, "
                        "at most the number of cores); ignored by --engine native")
    p.add_argument("--max-effects", type=int, default=4, help="most effects to add (default 4)")
    p.add_argument("--plot", default=None, metavar="PNG", help="figure (default: NEW.gap.png next to --out)")
    p.add_argument("--no-plot", action="store_true", help="write no figure")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_gap)


def _check_writable(path, what):
    d = Path(path).resolve().parent
    if Path(path).is_dir():
        raise InputError(f"{what} is a directory", str(path))
    if not d.is_dir() or not os.access(d, os.W_OK):
        raise InputError(f"cannot write {what}: folder {d} does not exist or is not writable", str(path))


def cmd_gap(args):
    from .cli import emit_json
    from .modelgap import card_at_rate, check_record, format_report, gap, plot_gap
    from .simulator import load_card
    card = load_card(args.model)
    if args.seeds < 3:
        raise InputError(f"--seeds must be at least 3, got {args.seeds}")
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be at least 1 (omit it for one per seed up to the cores), "
                         f"got {args.workers}")
    if args.max_effects < 0:
        raise InputError(f"--max-effects must be >= 0, got {args.max_effects}")
    _check_writable(args.out, "--out")
    plot = None if args.no_plot else (args.plot or str(Path(args.out).with_suffix("")) + ".gap.png")
    if plot:
        _check_writable(plot, "--plot")
    from .recording import read_recording
    rec = read_recording(args.input, rate_column=args.rate_column, time_column=args.time_column,
                         rate_unit=args.rate_unit, sample_rate_hz=args.sample_rate)
    check_record(rec.rate_deg_s, args.input)   # before the reader's notes: one line, not a note and an error
    for note in rec.notes:
        _log(f"gyrodenoise: note: {args.input}: {note}")
    if abs(card.sample_rate_hz - rec.sample_rate_hz) > 1e-6 * rec.sample_rate_hz:
        card_at_rate(card.text, rec.sample_rate_hz, card.source)   # refuse first (one line), then note
        _log(f"gyrodenoise: note: {args.model} says {card.sample_rate_hz:g} Hz, {args.input} is "
             f"{rec.sample_rate_hz:g} Hz: simulating at the record's rate; {args.out} keeps the card's")
    res = gap(rec.rate_deg_s, rec.sample_rate_hz, card, seeds=args.seeds, engine=args.engine,
              restarts=rec.restarts, max_effects=args.max_effects, fmu_dir=args.fmu_dir,
              workers=args.workers, source=args.input, quiet=False)
    text = res.card_text
    if res.effects_added:
        text = text.rstrip("\n") + f"\n# completed by gyrodenoise gap from {Path(args.input).name}: " + \
            ", ".join(e["name"] for e in res.effects_added) + f"; gap {res.gap_before:.3g} -> {res.gap_after:.3g}\n"
    # everything that can fail first; NEW.toml is written last, only after a successful run
    report = format_report(res, args.input)
    d = res.to_json()
    d.update({"out": str(args.out), "plot": plot, "source": str(args.input), "model": str(args.model)})
    if plot:
        plot_gap(res, plot, title=f"{Path(args.input).name} vs {Path(str(args.model)).name}")
    try:
        Path(args.out).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", args.out) from None
    if args.json:
        print(report, file=sys.stderr)
        emit_json(d)
    else:
        print(report)
        print(f"wrote {args.out}" + (f" and {plot}" if plot else ""))
    return 0
