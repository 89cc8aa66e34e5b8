"""The motion benchmark: an independent gyro simulator with moving profiles, baselines
tuned per run against the truth, the metrics that score a method against them, and real
moving gyros scored against a motion reference.

Command lines: ``benchmarks/tuned.py`` (simulated, tuned baselines) and
``benchmarks/real_motion.py`` (real gyros against a motion reference); both take
``--method FILE.py:FUNCTION`` for a method under development.

From Python (from the repository root, or with it on ``sys.path``)::

    from benchmarks.motion_bench import bench, realmotion
    fn = lambda rate_deg_s, sample_rate_hz: my_filter(rate_deg_s, sample_rate_hz)
    rows = bench.evaluate({"mine": fn}, seeds=(0,), quick=True)     # about 5 s
    print(bench.summarise(rows)["mine"])                            # geometric means, worst cell
    gains = bench.gain_table({"mine": fn}, quick=True)
    for line in bench.goal_lines(rows, gains, ["mine"]):
        print(line)

Modules: :mod:`~benchmarks.motion_bench.sim` (sensors, profiles),
:mod:`~benchmarks.motion_bench.baselines` (tuned filters), :mod:`~benchmarks.motion_bench.bench`
(metrics, goal lines), :mod:`~benchmarks.motion_bench.realmotion` (loaders, calibration,
rotation errors).
"""
