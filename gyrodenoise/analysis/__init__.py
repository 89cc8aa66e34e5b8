"""Analysis of gyro records: Allan variance (`allan`), spectra and peaks
(`spectrum`), motion kept and lag (`motion_metrics`), the paper's
tables (`experiments`) and the demo's figures (`plots`)."""
