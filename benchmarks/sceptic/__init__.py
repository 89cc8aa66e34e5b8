"""The sceptic's benchmark (issue 23): an independent gyro simulator, baselines
tuned per run against the truth, and the real-motion comparison.

Command lines: ``benchmarks/tuned.py`` (simulated, tuned baselines) and
``benchmarks/real_motion.py`` (real gyros against a motion reference); both take
``--method FILE.py:FUNCTION`` for a method under development.

From Python (with ``benchmarks/`` on ``sys.path``)::

    from sceptic import bench, realmotion
    fn = lambda rate_deg_s, sample_rate_hz: my_filter(rate_deg_s, sample_rate_hz)
    rows = bench.evaluate({"mine": fn}, seeds=(0,), quick=True)     # about 5 s
    print(bench.summarise(rows)["mine"])                            # geometric means, worst cell
    gains = bench.gain_table({"mine": fn}, quick=True)
    for line in bench.goal_lines(rows, gains, ["mine"]):
        print(line)

Modules: :mod:`sceptic.sim` (sensors, profiles), :mod:`sceptic.baselines`
(tuned filters), :mod:`sceptic.bench` (metrics, goal lines),
:mod:`sceptic.realmotion` (loaders, calibration, rotation errors).
"""
