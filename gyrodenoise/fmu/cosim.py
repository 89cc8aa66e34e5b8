"""The two-FMU system as an SSP file and through libcosimpy (Open Simulation
Platform), checked against the core."""

from __future__ import annotations

from pathlib import Path

from gyrodenoise.errors import InputError
from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.fmu.validation import _denoiser_params, _resolve_card, _restart_mask, compare_with_core


def _xml_attr(value):
    from xml.sax.saxutils import quoteattr
    return quoteattr(str(value)).replace("\n", "&#10;").replace("\r", "&#13;").replace("\t", "&#9;")


def _ssv_parameters(params, var_types):
    rows = []
    for name, value in params.items():
        kind = var_types[name]
        if kind == "Boolean":
            v = "true" if value else "false"
        elif kind == "Real":
            v = repr(float(value))
        elif kind == "Integer":
            v = str(int(value))
        else:
            v = str(value)
        rows.append(f'                  <ssv:Parameter name={_xml_attr(name)}>'
                    f'<ssv:{kind} value={_xml_attr(v)}/></ssv:Parameter>')
    return "\n".join(rows)


#: the name of the one parameter set of the SSP: every component's ParameterBinding holds a
#: ParameterSet of this name (a host that applies one named set at a time, as Ecos does,
#: applies them all; libcosim applies every binding whatever its name)
PARAMETER_SET_NAME = "parameters"


def card_parameter(card_obj, sensor="SimulatedFogNative"):
    """The value of the sensor FMU's ``card`` parameter for the card ``card_obj``: the name of the
    card bundled in the FMU when it is one of them (same numbers as the bundled card, whatever
    its file), else for SimulatedFogNative the compiled card on one line
    (:func:`gyrodenoise.fmu.simnative.compile_card`, ``one_line=True``) and for SimulatedFog
    (pythonfmu, which reads TOML only) the card's TOML text.

    One line, so that a host's result file stays one row per step (Ecos writes the String
    parameters into its CSV unquoted); only a non-bundled card for the pythonfmu sensor is
    multi-line."""
    from gyrodenoise.fmu.simnative import bundled_name, compile_card
    name = bundled_name(card_obj)
    if name is not None:
        return name
    if sensor == "SimulatedFogNative":
        return compile_card(card_obj, one_line=True)
    return card_obj.text


def system_parameters(card, seed=0, method=DEFAULT_METHOD, ar_order=3, rate_deg_s=0.0, denoiser_kw=None,
                      sensor="SimulatedFogNative"):
    """Parameter values of the two-FMU system: {instance: {variable: value}}.

    The fog's ``card``: :func:`card_parameter` (a bundled card's name, or the card in a form
    the sensor FMU reads)."""
    card_obj = _resolve_card(card)
    fs = card_obj.sample_rate_hz
    return card_obj, {
        "fog": {"card": card_parameter(card_obj, sensor), "seed": int(seed), "true_rate": float(rate_deg_s)},
        "denoiser": _denoiser_params(method, ar_order, fs, denoiser_kw),
    }


#: the denoiser and sensor FMUs an SSP or a libcosim run may use (same variables and outputs);
#: the first of each, the native ones, by default: a chain with no Python in it
DENOISERS = ("FogDenoiserNative", "FogDenoiser")
SENSORS = ("SimulatedFogNative", "SimulatedFog")


def _chain_paths(fmu_dir, denoiser, sensor="SimulatedFogNative"):
    """{"sensor": path, "denoiser": path} of the chain's two FMUs."""
    if denoiser not in DENOISERS:
        raise InputError(f"denoiser must be one of {', '.join(DENOISERS)}, got {denoiser!r}")
    if sensor not in SENSORS:
        raise InputError(f"sensor must be one of {', '.join(SENSORS)}, got {sensor!r}")
    paths = {}
    for role, name in (("sensor", sensor), ("denoiser", denoiser)):
        paths[role] = Path(fmu_dir) / f"{name}.fmu"
        if not paths[role].is_file():
            raise InputError(f"{paths[role]}: not found (run 'gyrodenoise fmu build --out {fmu_dir}')")
    return paths


def _ssp_component(inst, model, path, params):
    """The ``ssd:Component`` of instance ``inst`` (FMU ``model`` at ``path``), its parameters bound."""
    from fmpy import read_model_description
    md = read_model_description(str(path))
    types = {v.name: v.type for v in md.modelVariables}
    # the chain's free inputs (fog.true_rate, fog.restart: set by the parameter
    # binding / their start values) are not listed as connectors: fmpy's
    # simulate_ssp requires every listed input to be connected, and libcosim
    # refuses system-level connectors that would feed them
    free = {"true_rate", "restart"} if inst == "fog" else set()
    conns = "\n".join(
        f'          <ssd:Connector name={_xml_attr(v.name)} kind="{v.causality}">'
        f'<ssc:{v.type}/></ssd:Connector>'
        for v in md.modelVariables
        if v.causality in ("input", "output", "parameter") and v.name not in free)
    return f'''      <ssd:Component name="{inst}" type="application/x-fmu-sharedlibrary" source="resources/{model}.fmu">
        <ssd:Connectors>
{conns}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="{PARAMETER_SET_NAME}">
                <ssv:Parameters>
{_ssv_parameters(params, types)}
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>'''


def _system_structure(components, sensor, denoiser, card_name, seed, duration_s, step_s):
    """SystemStructure.ssd (text): the components, their two connections and the default experiment."""
    elements = "\n".join(components)
    return f'''<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="gyrodenoise_fmu_chain"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations">
  <ssd:System name="fog_chain" description="{sensor} (model card {_xml_attr(card_name)[1:-1]}, seed {int(seed)}) -> {denoiser}; one step = one sample">
    <ssd:Elements>
{elements}
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="fog" startConnector="measured_rate" endElement="denoiser" endConnector="raw_rate"/>
      <ssd:Connection startElement="fog" startConnector="restarted" endElement="denoiser" endConnector="restart"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0.0" stopTime="{float(duration_s)!r}">
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm>
          <osp:FixedStepAlgorithm baseStepSize="{step_s!r}"/>
        </osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
'''


def write_ssp(path, fmu_dir="build", card="paper_fog", seed=0, method=DEFAULT_METHOD, ar_order=3,
              rate_deg_s=0.0, duration_s=600.0, denoiser_kw=None, denoiser="FogDenoiserNative",
              sensor="SimulatedFogNative"):
    """Write an SSP 1.0 archive of the simulated gyro -> the denoiser; return its path.

    ``sensor``: ``"SimulatedFogNative"`` (default) or ``"SimulatedFog"`` (pythonfmu);
    ``denoiser``: ``"FogDenoiserNative"`` (default) or ``"FogDenoiser"`` (pythonfmu); each
    pair has the same variables and outputs. The default chain has no Python in it.

    The archive holds ``SystemStructure.ssd`` and both FMUs under ``resources/``;
    the connections are ``fog.measured_rate -> denoiser.raw_rate`` and
    ``fog.restarted -> denoiser.restart``; the parameters are bound inline;
    the step size (the card's sample period) is given in the OSP annotation of
    the default experiment (libcosim reads it) and is what any SSP master should use.
    """
    import zipfile
    chain = _chain_paths(fmu_dir, denoiser, sensor)
    paths = {sensor: chain["sensor"], denoiser: chain["denoiser"]}
    card_obj, params = system_parameters(card, seed, method, ar_order, rate_deg_s, denoiser_kw, sensor)
    components = [_ssp_component(inst, model, paths[model], params[inst])
                  for inst, model in (("fog", sensor), ("denoiser", denoiser))]
    ssd = _system_structure(components, sensor, denoiser, card_obj.name, seed, duration_s,
                            1.0 / card_obj.sample_rate_hz)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", ssd)
        for model, p in paths.items():
            z.write(p, f"resources/{model}.fmu")
    return path


def _step_nanoseconds(fs):
    """The sample period in ns (libcosim's time unit); InputError if not a whole number."""
    h_ns = int(round(1e9 / fs))
    if abs(h_ns * 1e-9 * fs - 1.0) > 1e-9:
        raise InputError(f"sample rate {fs} Hz is not a whole number of nanoseconds per sample "
                         "(libcosim's time unit)")
    return h_ns


def _libcosim_system(paths, params, vrs, h_ns, ssp_path=None):
    """The two-FMU system in libcosim, from the SSP at ``ssp_path`` or built from Python
    (local slaves, initial values, connections); (execution, fog index, denoiser index)."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave
    fvr, dvr = vrs["sensor"], vrs["denoiser"]
    if ssp_path is not None:
        ex = CosimExecution.from_ssp_file(str(ssp_path))
        fog = ex.slave_index_from_instance_name("fog")
        den = ex.slave_index_from_instance_name("denoiser")
    else:
        ex = CosimExecution.from_step_size(h_ns)
        fog = ex.add_local_slave(CosimLocalSlave(str(paths["sensor"]), "fog"))
        den = ex.add_local_slave(CosimLocalSlave(str(paths["denoiser"]), "denoiser"))
        setters = {"Real": ex.real_initial_value, "Integer": ex.integer_initial_value,
                   "Boolean": ex.boolean_initial_value, "String": ex.string_initial_value}
        for idx, inst, table in ((fog, "fog", fvr), (den, "denoiser", dvr)):
            for name, value in params[inst].items():
                vr, kind = table[name]
                setters[kind](idx, vr, value)
        ex.connect_real_variables(fog, fvr["measured_rate"][0], den, dvr["raw_rate"][0])
        ex.connect_boolean_variables(fog, fvr["restarted"][0], den, dvr["restart"][0])
    if fog < 0 or den < 0:
        raise RuntimeError("libcosim: the system has no instances 'fog' and 'denoiser'")
    return ex, fog, den


def _libcosim_steps(ex, fog, den, vrs, n, restarts):
    """Run ``n`` steps, a restart injected on ``fog.restart`` for the one step where
    ``restarts`` is set (an override manipulator); (measured, received, filtered, times,
    converged at the end, elapsed s)."""
    import time
    import numpy as np
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    fvr, dvr = vrs["sensor"], vrs["denoiser"]
    obs = CosimObserver.create_time_series(buffer_size=n + 16)
    ex.add_observer(obs)
    last = CosimObserver.create_last_value()
    ex.add_observer(last)
    for idx, vr in ((fog, fvr["measured_rate"][0]), (den, dvr["raw_rate"][0]),
                    (den, dvr["filtered_rate"][0])):
        obs.start_time_series(idx, vr, CosimVariableType.REAL)
    man = CosimManipulator.create_override()
    ex.add_manipulator(man)

    t0 = time.perf_counter()
    ok = True
    if not restarts.any():
        ok &= ex.step(n)
    else:
        k = int(np.flatnonzero(restarts)[0])
        ok &= ex.step(k)
        man.slave_boolean_values(fog, [fvr["restart"][0]], [True])
        ok &= ex.step(1)
        man.slave_boolean_values(fog, [fvr["restart"][0]], [False])
        ok &= ex.step(n - k - 1)
    elapsed = time.perf_counter() - t0
    if not ok:
        from libcosimpy.CosimExecution import get_last_error_message  # type: ignore[attr-defined]
        raise RuntimeError(f"libcosim: stepping failed: {get_last_error_message()}")

    def series(idx, vr):
        times, _, values = obs.time_series_real_samples(idx, vr, from_step=1, sample_count=n)
        return np.asarray(times, dtype=float) * 1e-9, np.asarray(values, dtype=float)

    times, measured = series(fog, fvr["measured_rate"][0])
    _, received = series(den, dvr["raw_rate"][0])
    _, filtered = series(den, dvr["filtered_rate"][0])
    converged = bool(last.last_boolean_values(den, [dvr["converged"][0]])[0])
    if not (len(measured) == len(received) == len(filtered) == n):
        raise RuntimeError(f"libcosim observer returned {len(measured)}/{len(received)}/"
                           f"{len(filtered)} samples, expected {n}")
    return measured, received, filtered, times, converged, elapsed


def cosim_run(fmu_dir="build", duration_s=60.0, rate_deg_s=0.0, restart_at_s=None, seed=0,
              card="paper_fog", method=DEFAULT_METHOD, ar_order=3, ssp=None, tol=1e-9,
              keep_arrays=False, denoiser_kw=None, denoiser="FogDenoiserNative", sensor="SimulatedFogNative"):
    """The two-FMU system in libcosim (Open Simulation Platform) via libcosimpy.

    ``ssp=None`` builds the system from Python (local slaves, connections,
    initial values); ``ssp=PATH`` writes an SSP archive there (:func:`write_ssp`)
    and loads the system from it. A restart is injected with an override
    manipulator on ``fog.restart`` for one step.

    libcosim's fixed-step master is of Jacobi type: the denoiser receives in step
    k the sensor's output at t_k, what it produced in step k-1; in step 0 its
    output after initialisation: the sensor's sample 0 (both sensor FMUs sample at
    fmi2ExitInitializationMode), no placeholder. The check is
    therefore that the denoiser's received samples are the sensor's outputs
    delayed by one step, that the sensor's samples equal ``gyrodenoise.simulate``,
    and that the denoiser's output equals ``gyrodenoise.denoise`` on the samples it
    received (``gyrodenoise.simulate``'s, no placeholder).
    """
    import numpy as np
    from fmpy import read_model_description
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.WARNING)

    card_obj, params = system_parameters(card, seed, method, ar_order, rate_deg_s, denoiser_kw, sensor)
    fs = card_obj.sample_rate_hz
    h_ns = _step_nanoseconds(fs)
    n = int(round(duration_s * fs))
    paths = _chain_paths(fmu_dir, denoiser, sensor)
    vrs = {m: {v.name: (v.valueReference, v.type) for v in read_model_description(str(p)).modelVariables}
           for m, p in paths.items()}
    ssp_path = None
    if ssp is not None:
        ssp_path = write_ssp(ssp, fmu_dir, card_obj, seed, method, ar_order, rate_deg_s, duration_s,
                             denoiser_kw, denoiser, sensor)
    ex, fog, den = _libcosim_system(paths, params, vrs, h_ns, ssp_path)
    restarts = _restart_mask(n, fs, restart_at_s)
    measured, received, filtered, times, converged, elapsed = _libcosim_steps(ex, fog, den, vrs, n, restarts)
    ex.stop()
    del ex
    res = {"case": {"master": "libcosim (SSP)" if ssp is not None else "libcosim (Python)",
                    "duration_s": n / fs, "n_samples": n, "sample_rate_hz": fs,
                    "true_rate_deg_s": float(rate_deg_s), "restart_at_s": restart_at_s,
                    "seed": int(seed), "card": card_obj.name, "method": method,
                    "ar_order": int(ar_order), "sensor": sensor, "denoiser": denoiser},
           "elapsed_s": elapsed, "two_fmu_steps_per_s": n / elapsed, "converged_at_end": converged,
           "step_size_s": float(np.median(np.diff(times))) if n > 1 else None,
           "first_received_deg_s": float(received[0]),
           "max_abs_diff_received_vs_delayed_measured_deg_s":
               float(np.max(np.abs(received[1:] - measured[:-1]))) if n > 1 else 0.0}
    res.update(_check_against_core(measured, received, filtered, restarts, rate_deg_s, card_obj, seed, method,
                                   ar_order, denoiser_kw, tol, res))
    if keep_arrays:
        res["arrays"] = {"measured": measured, "received": received, "filtered": filtered,
                         "time_s": times, "restarts": restarts}
    return res


def _check_against_core(measured, received, filtered, restarts, rate_deg_s, card_obj, seed, method, ar_order,
                        denoiser_kw, tol, res):
    """The comparisons with ``gyrodenoise.simulate`` and ``gyrodenoise.denoise`` and the verdict
    (``res`` holds the run's step size and delay check).

    ``measured[k]``: the sensor's output after step k (at t_(k+1)); ``received[k]``: the
    denoiser's input in step k (the sensor's output at t_k, Jacobi). Both sensor FMUs take
    sample 0 at fmi2ExitInitializationMode, so they produced ``received[0], measured[0], ...``
    (their samples 0..n, the restart injected before step k on sample k+1)."""
    import numpy as np
    from gyrodenoise.denoiser import denoise
    fs = card_obj.sample_rate_hz
    samples = np.concatenate(([received[0]], measured))
    sample_restarts = np.concatenate(([False], restarts))
    truth = np.full(len(samples), float(rate_deg_s))
    # what the denoiser received: the sensor's output at the start of each step, and the
    # restart flag of that sample (fog.restarted) with it
    rec_restarts = np.concatenate(([False], restarts[:-1]))
    cmp_ = compare_with_core(samples, samples, truth, sample_restarts, card_obj, seed, method, ar_order,
                             denoiser_kw)
    ref = denoise(received, fs, method=method, ar_order=ar_order, restarts=rec_restarts,
                  **(denoiser_kw or {}))
    out = {"max_abs_diff_measured_vs_simulate_deg_s": cmp_["max_abs_diff_measured_vs_simulate_deg_s"],
           "max_abs_diff_filtered_vs_denoise_deg_s": float(np.max(np.abs(filtered - ref))),
           "first_received_is_a_sample": True,     # sample 0, taken at initialisation
           "tolerance_deg_s": tol}
    out["ok"] = bool(res["max_abs_diff_received_vs_delayed_measured_deg_s"] == 0.0
                     and abs(res["step_size_s"] * fs - 1.0) < 1e-9
                     and out["max_abs_diff_measured_vs_simulate_deg_s"] <= tol
                     and out["max_abs_diff_filtered_vs_denoise_deg_s"] <= tol)
    return out
