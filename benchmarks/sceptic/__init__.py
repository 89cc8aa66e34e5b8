"""The sceptic's benchmark (issue 23): an independent gyro simulator, baselines
tuned per run against the truth, and the real-motion comparison.
See benchmarks/tuned.py and benchmarks/real_motion.py."""
