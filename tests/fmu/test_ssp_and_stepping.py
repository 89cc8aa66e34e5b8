"""What a third-party co-simulation host needs from the SSP archive and the FMUs' stepping.

* One parameter-set name in the whole archive (a host that applies one named set at a time,
  as Ecos does, applies every component's parameters), and libcosim still applies them.
* No parameter value with a newline (a host that writes the String parameters into its
  result CSV unquoted keeps one row per step): a bundled card bound by its name, any other
  card as the one-line compiled form, the sensor's numbers unchanged (``gyrodenoise.simulate``).
* Every FMU declares ``canHandleVariableCommunicationStepSize="false"`` (one step = one sample).
* A Jacobi master (get every output, set every input, step every FMU), run by hand with fmpy,
  feeds the denoiser ``gyrodenoise.simulate``'s samples (no placeholder sample): both sensor
  FMUs take sample 0 at fmi2ExitInitializationMode, and give the same outputs for the same calls.

References: ``gyrodenoise.simulate`` and ``gyrodenoise.denoise`` (the batch library,
themselves tested against the plain-Python specification), seeded.
"""
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu import cosim as C
from gyrodenoise.fmu import simnative
from tests.helpers import DATA, run_main

fmpy = pytest.importorskip("fmpy")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

from tests.fmu.fmi import Logger  # noqa: E402

SSV = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"
SSD = "{http://ssp-standard.org/SSP1/SystemStructureDescription}"
ALL_FMUS = ("FogDenoiser", "SimulatedFog", "FogDenoiserNative", "SimulatedFogNative")


@pytest.fixture(scope="module")
def fmu_dir(fmu_build):
    out, proc = fmu_build           # conftest: `gyrodenoise fmu build --out DIR`, once per session
    assert proc.returncode == 0, proc.stderr
    for name in ALL_FMUS:
        assert (out / f"{name}.fmu").is_file()
    return out


def _ssd(ssp):
    with zipfile.ZipFile(ssp) as z:
        return ET.fromstring(z.read("SystemStructure.ssd").decode())


def _bound(ssd):
    """{component: {set name: {parameter: value}}} of the archive's parameter bindings."""
    out = {}
    for comp in ssd.iter(f"{SSD}Component"):
        sets = out.setdefault(comp.get("name"), {})
        for ps in comp.iter(f"{SSV}ParameterSet"):
            sets.setdefault(ps.get("name"), {}).update(
                {p.get("name"): p[0].get("value") for p in ps.iter(f"{SSV}Parameter")})
    return out


class Slave:
    """One FMU instance in fmpy, its variables by name."""

    def __init__(self, fmu, tmp_path, instance):
        self.md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.log = Logger()
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(str(fmu), str(tmp_path / instance)),
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=instance)
        self.s.instantiate(callbacks=self.log.callbacks, loggingOn=True)

    def init(self, **params):
        self.s.setupExperiment(startTime=0.0)
        self.set(**params)
        self.s.enterInitializationMode()
        self.s.exitInitializationMode()

    def set(self, **values):
        for name, value in values.items():
            vr = [self.vr[name]]
            if isinstance(value, bool):
                self.s.setBoolean(vr, [value])
            elif isinstance(value, int):
                self.s.setInteger(vr, [value])
            elif isinstance(value, str):
                self.s.setString(vr, [value])
            else:
                self.s.setReal(vr, [float(value)])

    def real(self, name):
        return self.s.getReal([self.vr[name]])[0]

    def boolean(self, name):
        return bool(self.s.getBoolean([self.vr[name]])[0])

    def free(self):
        self.s.terminate()
        self.s.freeInstance()


# --------------------------------------------------------------- SSP parameters
def test_one_parameter_set_name_holds_every_component_parameters(fmu_dir, tmp_path):
    """Non-default card (imar_fog, 400 Hz), method, order, seed and rate: one set name in the
    archive, each component's parameters in a set of that name."""
    ssp = C.write_ssp(tmp_path / "chain.ssp", fmu_dir=fmu_dir, card="imar_fog", seed=3, method="shakf",
                      ar_order=4, rate_deg_s=2.5, duration_s=2.0)
    ssd = _ssd(ssp)
    names = {ps.get("name") for ps in ssd.iter(f"{SSV}ParameterSet")}
    assert names == {C.PARAMETER_SET_NAME}
    bound = _bound(ssd)
    assert set(bound) == {"fog", "denoiser"}
    fog = bound["fog"][C.PARAMETER_SET_NAME]
    den = bound["denoiser"][C.PARAMETER_SET_NAME]
    assert fog == {"card": "imar_fog", "seed": "3", "true_rate": "2.5"}
    assert den["method"] == "shakf" and den["ar_order"] == "4"
    assert float(den["sample_period"]) == 1.0 / 400.0


@pytest.mark.slow
@pytest.mark.parametrize("sensor", ["SimulatedFogNative", "SimulatedFog"])
def test_libcosim_applies_the_shared_set(fmu_dir, tmp_path, sensor):
    """libcosim loads the archive (one set name) and applies every parameter: the sensor's
    samples are imar_fog's at 400 Hz with seed 3 and rate 2.5 deg/s, the denoiser's output
    is shakf's of order 4 (not the defaults paper_fog / motion / 0.005 s)."""
    pytest.importorskip("libcosimpy")
    kw = dict(duration_s=3.0, rate_deg_s=2.5, seed=3, card="imar_fog", method="shakf", ar_order=4)
    res = C.cosim_run(fmu_dir, ssp=tmp_path / "chain.ssp", sensor=sensor, keep_arrays=True, **kw)
    assert res["step_size_s"] == pytest.approx(1.0 / 400.0, rel=1e-9)
    assert res["max_abs_diff_measured_vs_simulate_deg_s"] == 0.0
    assert res["max_abs_diff_filtered_vs_denoise_deg_s"] <= 1e-9
    assert res["ok"]
    received = res["arrays"]["received"]
    # the defaults would give another output: motion on the same samples differs
    assert np.max(np.abs(gd.denoise(received, 400.0) - res["arrays"]["filtered"])) > 1e-6


# --------------------------------------------------------------- the card parameter
def test_no_parameter_value_has_a_newline(fmu_dir, tmp_path):
    """A bundled card is bound by its name (also when given as a path), any other card as the
    one-line compiled form: no value with a newline, a comma, a semicolon or a quote."""
    bundled = simnative.bundled_cards()["imar_fog"]
    for card, expected in (("imar_fog", "imar_fog"), (bundled, "imar_fog"), ("paper_fog", "paper_fog")):
        assert C.card_parameter(gd.load_card(card)) == expected
    custom = DATA / "every_term.toml"
    ssp = C.write_ssp(tmp_path / "chain.ssp", fmu_dir=fmu_dir, card=custom, method="kf")
    values = [v for sets in _bound(_ssd(ssp)).values() for params in sets.values() for v in params.values()]
    assert values and all(not any(ch in v for ch in "\n\r,;\"") for v in values), values
    card = next(v for v in values if v.startswith("gdcard"))
    assert card == simnative.compile_card(custom, one_line=True)


def test_one_line_card_gives_the_same_numbers(fmu_dir, tmp_path):
    """SimulatedFogNative with the one-line compiled card (text, or the file `gyrodenoise fmu
    card --one-line` writes), the multi-line compiled card and (for a bundled card) its name:
    the same samples, equal to gyrodenoise.simulate."""
    custom = DATA / "every_term.toml"
    card_file = tmp_path / "every_term.gdcard"
    rc, _, err = run_main("fmu", "card", str(custom), "--one-line", "--out", str(card_file))
    assert rc == 0, err
    assert len(card_file.read_text().splitlines()) == 1
    n = 300
    runs = {}
    for label, card in (("one-line", simnative.compile_card(custom, one_line=True)),
                        ("one-line file", str(card_file)),
                        ("multi-line", simnative.compile_card(custom)),
                        ("name", "imar_fog"), ("imar one-line", simnative.compile_card("imar_fog", one_line=True))):
        s = Slave(fmu_dir / "SimulatedFogNative.fmu", tmp_path, label.replace(" ", "_"))
        s.init(card=card, seed=5, true_rate=1.5)      # sample 0 at fmi2ExitInitializationMode
        out = [s.real("measured_rate")]
        for k in range(n - 1):
            s.s.doStep(k * 1e-3, 1e-3)    # the step size is not checked here (strict_step_size off)
            out.append(s.real("measured_rate"))
        s.free()
        runs[label] = np.array(out)
    ref = gd.simulate(gd.load_card(custom), n, seed=5, true_rate_deg_s=1.5).rate_deg_s
    for label in ("one-line", "one-line file", "multi-line"):
        assert np.array_equal(runs[label], ref), label
    imar = gd.simulate("imar_fog", n, seed=5, true_rate_deg_s=1.5).rate_deg_s
    assert np.array_equal(runs["name"], imar) and np.array_equal(runs["imar one-line"], imar)


@pytest.mark.parametrize("damage,reason", [
    (lambda t: t.rsplit(" | ", 1)[0], "of the 125 card fields"),
    (lambda t: t.replace(" | Q 0x", " | Q 0y", 1), "expected 0x and the 16 hex digits"),
    (lambda t: t.replace(" | N ", " | X ", 1), "field N expected"),
])
def test_bad_one_line_card_refused_with_the_reason(fmu_dir, tmp_path, damage, reason):
    s = Slave(fmu_dir / "SimulatedFogNative.fmu", tmp_path, "bad")
    s.s.setupExperiment(startTime=0.0)
    s.set(card=damage(simnative.compile_card("paper_fog", one_line=True)))
    s.s.enterInitializationMode()
    with pytest.raises(FMICallException):
        s.s.exitInitializationMode()
    assert any(reason in m for m in s.log.errors()), s.log.messages
    s.s.freeInstance()


# --------------------------------------------------------------- step size
@pytest.mark.parametrize("name", ALL_FMUS)
def test_fixed_communication_step_size_declared(fmu_dir, name):
    md = read_model_description(str(fmu_dir / f"{name}.fmu"))
    assert md.coSimulation.canHandleVariableCommunicationStepSize is False
    with zipfile.ZipFile(fmu_dir / f"{name}.fmu") as z:
        assert 'canHandleVariableCommunicationStepSize="false"' in z.read("modelDescription.xml").decode()


# --------------------------------------------------------------- the first sample
@pytest.mark.parametrize("sensor", ["SimulatedFogNative", "SimulatedFog"])
@pytest.mark.parametrize("method", ["shakf", "motion"])
def test_jacobi_master_feeds_the_denoiser_the_library_samples(fmu_dir, tmp_path, method, sensor):
    """A Jacobi master by hand (get every output, then set every input, then step every FMU),
    imar_fog at 400 Hz, a restart injected: the denoiser receives gyrodenoise.simulate's
    samples from the first step on (no placeholder: the sensor takes sample 0 at
    fmi2ExitInitializationMode), and its output equals gyrodenoise.denoise on them, bit for
    bit (with the sensor's start value 0 deg/s as first input it differed at 1 s by up to
    7.3e-3 deg/s)."""
    n, fs, seed, rate = 800, 400.0, 4, 3.0
    h = 1.0 / fs
    restart_step = 500                        # restart set on fog.restart before this step
    fog = Slave(fmu_dir / f"{sensor}.fmu", tmp_path, "fog")
    den = Slave(fmu_dir / "FogDenoiserNative.fmu", tmp_path, "den")
    fog.init(card="imar_fog", seed=seed, true_rate=rate)
    den.init(method=method, sample_period=h)
    received, received_rs, filtered = [], [], []
    for k in range(n):
        z, rs = fog.real("measured_rate"), fog.boolean("restarted")     # get every output
        den.set(raw_rate=z, restart=rs)                                   # set every input
        fog.set(restart=k == restart_step)
        fog.s.doStep(k * h, h)                                            # step every FMU
        den.s.doStep(k * h, h)
        received.append(z)
        received_rs.append(rs)
        filtered.append(den.real("filtered_rate"))
    fog.free()
    den.free()
    restarts = np.zeros(n, dtype=bool)
    restarts[restart_step + 1] = True         # the restart reaches the sample at the step's end
    samples = gd.simulate("imar_fog", n, seed=seed, true_rate_deg_s=rate, restarts=restarts).rate_deg_s
    assert np.array_equal(np.array(received), samples)
    assert np.array_equal(np.array(received_rs), restarts)
    ref = gd.denoise(samples, fs, method=method, restarts=restarts)
    assert np.array_equal(np.array(filtered), ref)
    # the restart took effect (the output without it differs)
    assert np.max(np.abs(gd.denoise(samples, fs, method=method) - ref)) > 1e-9


def test_both_sensor_kinds_give_the_same_outputs_for_the_same_calls(fmu_dir, tmp_path):
    """SimulatedFog (pythonfmu) and SimulatedFogNative, the same calls (true rate and restart set
    in initialisation mode, then set before each step, a restart on sample 0 and one later):
    the same measured_rate and restarted after fmi2ExitInitializationMode and after each step,
    equal to gyrodenoise.simulate's samples; both declare them initial="calculated" (no start)
    and list them as InitialUnknowns."""
    n, fs, seed = 300, 400.0, 6
    h = 1.0 / fs
    truth = 2.0 + np.sin(np.arange(n) / 40.0)
    restarts = np.zeros(n, dtype=bool)
    restarts[[0, 170]] = True
    got = {}
    for sensor in ("SimulatedFog", "SimulatedFogNative"):
        md = read_model_description(str(fmu_dir / f"{sensor}.fmu"))
        declared = {v.name: v for v in md.modelVariables}
        index = {v.name: i + 1 for i, v in enumerate(md.modelVariables)}
        for name in ("measured_rate", "restarted"):
            assert declared[name].initial == "calculated" and declared[name].start is None, (sensor, name)
        assert sorted(u.variable.name for u in md.initialUnknowns) == ["measured_rate", "restarted"], sensor
        assert all(index[u.variable.name] for u in md.initialUnknowns)
        fog = Slave(fmu_dir / f"{sensor}.fmu", tmp_path, sensor)
        fog.init(card="imar_fog", seed=seed, true_rate=float(truth[0]), restart=bool(restarts[0]))
        out, out_rs = [fog.real("measured_rate")], [fog.boolean("restarted")]
        for k in range(1, n):
            fog.set(true_rate=float(truth[k]), restart=bool(restarts[k]))
            fog.s.doStep((k - 1) * h, h)
            out.append(fog.real("measured_rate"))
            out_rs.append(fog.boolean("restarted"))
        fog.free()
        got[sensor] = (np.array(out), np.array(out_rs))
    ref = gd.simulate("imar_fog", n, seed=seed, true_rate_deg_s=truth, restarts=restarts).rate_deg_s
    for sensor, (out, out_rs) in got.items():
        assert np.array_equal(out, ref), sensor
        assert np.array_equal(out_rs, restarts), sensor


@pytest.mark.parametrize("sensor", ["SimulatedFogNative", "SimulatedFog"])
def test_a_non_finite_true_rate_at_initialisation_is_refused_with_the_reason(fmu_dir, tmp_path, sensor):
    """Sample 0 is taken at fmi2ExitInitializationMode: a NaN true rate then is refused there,
    the reason logged, in both sensor kinds."""
    fog = Slave(fmu_dir / f"{sensor}.fmu", tmp_path, "nan")
    fog.s.setupExperiment(startTime=0.0)
    fog.set(true_rate=float("nan"))
    fog.s.enterInitializationMode()
    with pytest.raises(FMICallException):
        fog.s.exitInitializationMode()
    assert any("true_rate is nan" in m and "first sample" in m for m in fog.log.errors()), fog.log.messages
    fog.s.freeInstance()


# --------------------------------------------------------------- Ecos
ECOS_RUN = """
import json, sys
from ecospy import EcosSimulation
ssp, h, n, set_name = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
sim = EcosSimulation(ssp_path=ssp, step_size=h)
sim.init(parameter_set=set_name)
received, filtered = [], []
for k in range(n):
    received.append(sim.get_real("denoiser::raw_rate"))     # the input of step k
    sim.step()
    filtered.append(sim.get_real("denoiser::filtered_rate"))
card = sim.get_string("fog::card")
sim.terminate()
sim.free()
print(json.dumps({"received": received, "filtered": filtered, "card": card}))
"""


def _tbb_lib_dir():
    """The folder of libtbb.so.12 from the tbb wheel (ecospy's engine links it), or None."""
    import sys
    from pathlib import Path
    for d in (Path(sys.prefix) / "lib", Path(sys.base_prefix) / "lib"):
        if any(d.glob("libtbb.so.12*")):
            return d
    return None


@pytest.mark.slow
def test_ecos_runs_the_ssp_with_its_parameters(fmu_dir, tmp_path):
    """Ecos (ecospy, a co-simulation engine nobody here wrote) loads the archive, applies the one
    named parameter set (imar_fog at 400 Hz, seed 3, 2.5 deg/s, shakf): the denoiser receives
    gyrodenoise.simulate's samples (from sample 0 on, Jacobi, no placeholder) and outputs
    gyrodenoise.denoise's of what it received, bit for bit. In a fresh
    process, with the tbb wheel's lib folder on LD_LIBRARY_PATH."""
    import json
    import os
    import subprocess
    import sys
    import importlib.util
    if importlib.util.find_spec("ecospy") is None:     # not imported here: it loads libtbb at import
        pytest.skip("ecospy not installed (pip install ecospy tbb)")
    tbb = _tbb_lib_dir()
    if tbb is None:
        pytest.skip("libtbb.so.12 not found (pip install tbb)")
    n, fs = 400, 400.0
    ssp = C.write_ssp(tmp_path / "chain.ssp", fmu_dir=fmu_dir, card="imar_fog", seed=3, method="shakf",
                      rate_deg_s=2.5, duration_s=n / fs)
    env = dict(os.environ, LD_LIBRARY_PATH=os.pathsep.join(
        p for p in (str(tbb), os.environ.get("LD_LIBRARY_PATH", "")) if p))
    proc = subprocess.run([sys.executable, "-c", ECOS_RUN, str(ssp), repr(1.0 / fs), str(n),
                           C.PARAMETER_SET_NAME], capture_output=True, text=True, timeout=120, env=env,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["card"] == "imar_fog"
    samples = gd.simulate("imar_fog", n, seed=3, true_rate_deg_s=2.5).rate_deg_s
    received = np.array(out["received"])
    # Jacobi: the denoiser receives the sensor's output at the start of each step: sample 0
    # (taken at fmi2ExitInitializationMode) first, then the sample of each step, no placeholder
    assert np.array_equal(received, samples)
    assert np.array_equal(np.array(out["filtered"]), gd.denoise(received, fs, method="shakf"))
