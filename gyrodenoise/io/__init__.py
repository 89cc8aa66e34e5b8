"""Files in and out: recordings (CSV, `recording`), PSINS text records
(`psins`), noise terms for Kalibr and MATLAB (`export`)."""
