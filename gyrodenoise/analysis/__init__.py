"""Analysis of gyro records: Allan variance (:mod:`.allan`), spectra and peaks
(:mod:`.spectrum`), motion kept and lag (:mod:`.motion_metrics`), the paper's
tables (:mod:`.experiments`) and the demo's figures (:mod:`.plots`)."""
