"""Files in and out: recordings (CSV, :mod:`.recording`), PSINS text records
(:mod:`.psins`), noise terms for Kalibr and MATLAB (:mod:`.export`)."""
