"""MAVLink / DataFlash / ULog bridge of gyrodenoise.

Reads autopilot logs (telemetry ``.tlog``, ArduPilot DataFlash ``.bin``, PX4
``.ulg``) and live MAVLink links, finds every gyro stream, denoises each axis
with its own :class:`gyrodenoise.Denoiser`, and writes a filtered copy of the
log in which only the gyro fields of the IMU messages differ.

Modules, by concern. Imports go one way: a module imports only modules after it
in the chain ``process`` (the re-export), ``dispatch``, ``cluster``, ``pipeline``,
(``formats``, ``filtering``, ``report``, ``plotting``), (``spectra``, ``engines``,
``checks``, ``output``), (``dataflash``, ``tlog``, ``ulog``), (``streams``,
``stopping``); ``live`` and ``fleet`` stand beside it.

Reading and writing logs:

* :mod:`gyrodenoise.mavlink.streams` -- the in-memory gyro stream, restart detection, noise figures
* :mod:`gyrodenoise.mavlink.dataflash` -- DataFlash ``.bin`` scanner / patcher (numpy, no per-message objects)
* :mod:`gyrodenoise.mavlink.tlog` -- telemetry-log framer, IMU decoding and re-packing (CRC checked)
* :mod:`gyrodenoise.mavlink.ulog` -- PX4 ULog via pyulog
* :mod:`gyrodenoise.mavlink.formats` -- which format a file is; read its gyro streams, write the filtered copy

One log:

* :mod:`gyrodenoise.mavlink.engines` -- the native batch engine and the FogDenoiser FMU engine (fmpy)
* :mod:`gyrodenoise.mavlink.filtering` -- the streams through the filter; why a stream is left unfiltered
* :mod:`gyrodenoise.mavlink.checks` -- usable samples, the safety net on the output, gyro saturation
* :mod:`gyrodenoise.mavlink.report` -- the report of a stream (noise, motion kept) and its stderr lines
* :mod:`gyrodenoise.mavlink.output` -- the per-stream CSV and file names
* :mod:`gyrodenoise.mavlink.plotting` -- the stream plots, drawn inline or in forked helper processes
* :mod:`gyrodenoise.mavlink.spectra` -- the spectrum of a stream, for the report and its PNG
* :mod:`gyrodenoise.mavlink.pipeline` -- one log end to end (``process_log``)

Many logs, live links:

* :mod:`gyrodenoise.mavlink.cluster` -- one log as one task, on a Dask cluster or fsspec URLs; progress
* :mod:`gyrodenoise.mavlink.dispatch` -- many logs, serially, in a process pool or on a cluster (``process_many``)
* :mod:`gyrodenoise.mavlink.stopping` -- child processes, signals and partial files
* :mod:`gyrodenoise.mavlink.fleet` -- the fleet report from a run's summary
* :mod:`gyrodenoise.mavlink.live` -- live link forwarding, sample by sample
* :mod:`gyrodenoise.mavlink.process` -- the names above that the command line uses, in one place

The command: :mod:`gyrodenoise.cli.mavlink` (``gyrodenoise mavlink``).
"""
