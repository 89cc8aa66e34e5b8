"""``gyrodenoise fmu build`` and ``gyrodenoise fmu run``: thin CLI over the
modules of this package."""

from __future__ import annotations

import sys
from pathlib import Path

from gyrodenoise._extras import require
from gyrodenoise.cli.options import add_filter_options
from gyrodenoise.cli.program import emit_json
from gyrodenoise.console import log
from gyrodenoise.errors import InputError
from gyrodenoise.fmu.build import FMUS, build_all, stale_reason
from gyrodenoise.fmu.cosim import cosim_run
from gyrodenoise.fmu.validation import _resolve_card, validation_run


def register_cli(subparsers):
    """Add ``gyrodenoise fmu build`` and ``gyrodenoise fmu run``."""
    p = subparsers.add_parser("fmu", help="build and check the FMUs (FMI 2.0 co-simulation)",
                              description="Build FogDenoiser.fmu and SimulatedFog.fmu, and run the "
                                          "two-FMU validation against the core.")
    sub = p.add_subparsers(dest="fmu_command", metavar="ACTION")
    _register_build(sub)
    _register_card(sub)
    _register_run(sub)
    p.set_defaults(func=lambda args: (p.print_help(sys.stderr), 2)[1])


def _register_build(sub):
    b = sub.add_parser("build", help="build FogDenoiser.fmu, SimulatedFog.fmu (pythonfmu), "
                                     "FogDenoiserNative.fmu, SimulatedFogNative.fmu and the 3-axis FogDenoiserImuNative.fmu "
                                     "(C, no Python needed), and the FMI 3.0 versions FogDenoiserNative3.fmu, SimulatedFogNative3.fmu "
                                     "with the 3-axis FogDenoiserImuNative3.fmu",
                       description="Package gyrodenoise/fmu/sources/*.py with pythonfmu (in a subprocess) and the "
                                   "core (plain-Python kernels + the C extension) into FMI 2.0 "
                                   "co-simulation FMUs, and compile FogDenoiserNative.fmu, "
                                   "SimulatedFogNative.fmu and FogDenoiserImuNative.fmu (3 axes, one scalar an axis) "
                                   "from the C cores and their FMI layer (gyrodenoise/fmu/sources/native) "
                                   "for linux64 and aarch64-linux (glibc 2.17), win64, darwin64 and aarch64-darwin "
                                   "(zig from the ziglang package; mingw-w64 for win64). The FMI 3.0 FMUs "
                                   "(FogDenoiserNative3, SimulatedFogNative3, FogDenoiserImuNative3) come from the same "
                                   "C sources, their binaries in the FMI 3.0 platform folders (x86_64-linux, "
                                   "aarch64-linux, x86_64-windows, x86_64-darwin, aarch64-darwin). Every FMU carries "
                                   "reference results (documentation/<Model>_in.csv and <Model>_ref.csv).")
    b.add_argument("--out", default="build", metavar="DIR", help="output folder (default: build/)")
    b.add_argument("--platforms", default=None, metavar="LIST",
                   help="native FMU platforms, comma-separated, each required (linux64, win64, "
                        "darwin64, aarch64-linux, aarch64-darwin); default: every platform a compiler "
                        "is found for (zig from the ziglang package: all five), the others skipped "
                        "with the reason")
    b.add_argument("--fmi-versions", default="2,3", metavar="LIST",
                   help="FMI versions to build, comma-separated: 2 (the pythonfmu and native FMI 2.0 FMUs), "
                        "3 (the native FMI 3.0 FMUs); default: 2,3")
    b.set_defaults(func=_cmd_build)


def _register_card(sub):
    c = sub.add_parser("card", help="compile a model card for SimulatedFogNative.fmu",
                       description="Compile a model card (TOML path or embedded name) into the form "
                                   "SimulatedFogNative.fmu reads (its card parameter takes the compiled "
                                   "text or the file's path): the card vector, each value as its IEEE 754 bits.")
    c.add_argument("card", help="model card path or embedded name (e.g. paper_fog)")
    c.add_argument("--out", default=None, metavar="FILE", help="write the compiled card there (default: stdout)")
    c.add_argument("--one-line", action="store_true",
                   help="the fields on one line, separated by ' | ' (the form for a parameter value that a "
                        "host writes into its result file, e.g. an SSP parameter binding)")
    c.set_defaults(func=_cmd_card)


def _register_run(sub):
    r = sub.add_parser("run", help="SimulatedFog -> FogDenoiser validation run (fmpy or libcosim)",
                       description="Run SimulatedFog -> FogDenoiser one sample per step and compare "
                                   "with the core's batch output (1e-9) and Allan reduction. Without "
                                   "--rate, runs a static and a constant-rate case, each with a "
                                   "restart in the middle. Exit status 1 when a check fails.")
    r.add_argument("--fmu-dir", default="build", metavar="DIR",
                   help="folder of the FMUs (default: build/; built there when missing)")
    r.add_argument("--duration", type=float, default=600.0, metavar="S",
                   help="length of each case, s (default 600)")
    r.add_argument("--rate", type=float, default=None, metavar="DEG_S",
                   help="run one case at this constant true rate, deg/s")
    r.add_argument("--constant-rate", type=float, default=10.0, metavar="DEG_S",
                   help="true rate of the constant-rate case, deg/s (default 10)")
    r.add_argument("--restart-at", type=float, default=None, metavar="S",
                   help="time of the restart, s (default: the middle); negative: no restart")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--card", default="paper_fog", help="model card path or embedded name")
    add_filter_options(r, ("--method", "--ar-order"), help={"--method": None, "--ar-order": None})
    r.add_argument("--master", default="fmpy", choices=["fmpy", "libcosim", "ssp"],
                   help="fmpy FMU2Slave loop (default), libcosim built from Python, or "
                        "libcosim from an SSP file written next to the FMUs (libcosim and the SSP "
                        "run SimulatedFogNative.fmu -> FogDenoiserNative.fmu: no Python in the chain)")
    r.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    r.set_defaults(func=_cmd_run)


def _cmd_build(args):
    require("fmu", "fmpy", "pythonfmu", what="gyrodenoise fmu build")   # the FMI headers, the Python FMUs
    from gyrodenoise.fmu.native import PLATFORMS
    from gyrodenoise.fmu.native3 import build_native_fmus
    platforms = None
    if args.platforms is not None:
        platforms = [p.strip() for p in args.platforms.split(",") if p.strip()]
        bad = [p for p in platforms if p not in PLATFORMS]
        if bad or not platforms:
            raise InputError(f"--platforms: unknown platform {', '.join(bad) or '(none given)'}; "
                             f"known: {', '.join(PLATFORMS)}")
    versions = _fmi_versions(args.fmi_versions)
    report = {}
    native = build_native_fmus(args.out, platforms=platforms, report=report,    # compilers first: fails fast
                               fmi_versions=versions)
    paths = build_all(args.out) if 2 in versions else {}
    paths.update(native)
    for name, path in paths.items():
        print(f"{name}: {path}")
    for plat, what in report.items():
        log(f"gyrodenoise: native {plat}: {what}")
    return 0


def _fmi_versions(text):
    """The FMI versions (a tuple of 2 and/or 3) of a --fmi-versions value; InputError if bad."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    bad = [p for p in parts if p not in ("2", "3")]
    if bad or not parts:
        raise InputError(f"--fmi-versions: {', '.join(bad) or '(none given)'} is not an FMI version "
                         "this command builds; known: 2, 3")
    return tuple(sorted({int(p) for p in parts}))


def _cmd_card(args):
    from gyrodenoise.fmu.simnative import compile_card
    text = compile_card(args.card, one_line=args.one_line)  # a bad card: InputError (exit 2), nothing written
    if args.one_line:
        text += "\n"
    if args.out is None:
        sys.stdout.write(text)
        return 0
    out = Path(args.out)
    if out.is_dir():
        raise InputError(f"--out {out}: is a folder, expected a file name")
    try:
        out.write_text(text)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write: {exc.strerror}") from None
    log(f"SimulatedFogNative card: {out}")
    return 0


def _cmd_run(args):
    require("fmu", "fmpy", "pythonfmu", what="gyrodenoise fmu run")     # the master, a stale FMU rebuilt
    fmu_dir = Path(args.fmu_dir)
    _resolve_card(args.card)          # a bad card is a user error before anything runs
    _rebuild_stale(fmu_dir, native=args.master != "fmpy")
    if args.duration <= 0:
        raise InputError(f"--duration must be > 0 s, got {args.duration}")
    results = {}
    for case, kw in _cases(args).items():
        log(f"gyrodenoise: fmu run: {case} ({args.master})")
        if args.master == "fmpy":
            results[case] = validation_run(fmu_dir, **kw)
        else:
            ssp = fmu_dir / "gyrodenoise_fog_chain.ssp" if args.master == "ssp" else None
            results[case] = cosim_run(fmu_dir, ssp=ssp, **kw)
    ok = all(r["ok"] for r in results.values())
    if args.json:
        emit_json({"master": args.master, "cases": results, "ok": ok})
    else:
        print(_format_results(results))
        print("ok" if ok else "FAILED: FMU output differs from the core", flush=True)
    return 0 if ok else 1


def _rebuild_stale(fmu_dir, native):
    """(Re)build the FMUs in ``fmu_dir`` that are missing or stale, saying why; ``native``: also
    the native FMUs (the chain libcosim and the SSP run)."""
    reasons = {n: stale_reason(fmu_dir / f"{n}.fmu") for n in FMUS}
    if any(reasons.values()):
        why = "; ".join(f"{n}: {r}" for n, r in reasons.items() if r)
        log(f"gyrodenoise: (re)building the FMUs in {fmu_dir}/ ({why})")
        build_all(fmu_dir)
    if native:
        from gyrodenoise.fmu.native import DENOISER, build_native_fmus, native_stale_reason
        from gyrodenoise.fmu.simnative import SIMULATED_FOG_NATIVE
        why = {spec.name: native_stale_reason(fmu_dir / f"{spec.name}.fmu", spec)
               for spec in (DENOISER, SIMULATED_FOG_NATIVE)}
        if any(why.values()):
            log(f"gyrodenoise: (re)building the native FMUs in {fmu_dir}/ ("
                + "; ".join(f"{n}: {r}" for n, r in why.items() if r) + ")")
            build_native_fmus(fmu_dir)


def _cases(args):
    """case name -> the validation run's keywords: one case at --rate, else static and constant rate."""
    if args.rate is not None:
        rates = {"constant_rate": args.rate}
    else:
        rates = {"static": 0.0, "constant_rate": args.constant_rate}
    if args.restart_at is None:
        restart_at = args.duration / 2
    else:
        restart_at = None if args.restart_at < 0 else args.restart_at
    return {case: dict(duration_s=args.duration, rate_deg_s=rate, restart_at_s=restart_at, seed=args.seed,
                       card=args.card, method=args.method, ar_order=args.ar_order)
            for case, rate in rates.items()}


def _format_results(results):
    lines = []
    for case, r in results.items():
        c = r["case"]
        lines.append(f"== {case}: {c['duration_s']:g} s at {c['sample_rate_hz']:g} Hz, true rate "
                     f"{c['true_rate_deg_s']:g} deg/s, restart at {c['restart_at_s']} s, "
                     f"{c['method']} AR({c['ar_order']}), seed {c['seed']}")
        lines.append(f"   {r['elapsed_s']:.2f} s, {r['two_fmu_steps_per_s']:.0f} two-FMU steps/s")
        lines.append(f"   max |FMU measured - simulate|  = {r['max_abs_diff_measured_vs_simulate_deg_s']:.3g} deg/s")
        lines.append(f"   max |FMU filtered - denoise|   = {r['max_abs_diff_filtered_vs_denoise_deg_s']:.3g} deg/s")
        if "allan" in r:
            a = r["allan"]
            lines.append("   Allan term      raw        FMU filt   batch filt  reduction FMU / batch")
            for k in ("N", "B", "K", "R", "Q"):
                rf, rb = r["reduction_fmu"][k], r["reduction_batch"][k]
                fmt = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
                lines.append(f"   {k}  {a['raw'][k]:11.4g} {a['fmu_filtered'][k]:11.4g} "
                             f"{a['batch_filtered'][k]:11.4g}   {fmt(rf)} / {fmt(rb)}")
        lines.append(f"   {'ok' if r['ok'] else 'FAILED'}")
    return "\n".join(lines)
