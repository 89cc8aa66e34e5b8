"""Flight logs of gyrodenoise: MAVLink telemetry, DataFlash and ULog logs, and live MAVLink links.

Reads autopilot logs (telemetry ``.tlog``, ArduPilot DataFlash ``.bin``, PX4
``.ulg``) and live MAVLink links, finds every gyro stream, denoises each axis
with its own :class:`gyrodenoise.Denoiser`, and writes a filtered copy of the
log in which only the gyro fields of the IMU messages differ.

Modules, by concern. Imports go one way: a module imports only modules after it
in the chain ``process`` (the re-export), ``dispatch``, ``cluster``, ``pipeline``,
(``formats``, ``log_review``, ``filtering``, ``report``, ``plotting``), ``adapters``, (the
review modules ``segments``, ``vibration``, ``parameters``, ``filter_review``,
``vehicle_filters``, ``events``, ``vehicle_rate``; ``spectra``, ``engines``, ``checks``,
``output``), (``dataflash``, ``tlog``, ``ulog``, ``logdata``), ``model``, (``streams``,
``stopping``); ``autopilots`` is imported by the modules that need a strategy (its
strategies import the review modules inside their methods); ``live`` and ``fleet``
stand beside it.

Reading and writing logs:

* :mod:`gyrodenoise.flightlog.streams` -- the in-memory gyro stream, restart detection, noise figures
* :mod:`gyrodenoise.flightlog.dataflash` -- DataFlash ``.bin`` scanner / patcher (numpy, no per-message objects)
* :mod:`gyrodenoise.flightlog.tlog` -- telemetry-log framer, IMU decoding and re-packing (CRC checked)
* :mod:`gyrodenoise.flightlog.ulog` -- PX4 ULog via pyulog
* :mod:`gyrodenoise.flightlog.model` -- the typed log: ``FlightLog``, its boots and time bases, facts, evidence
* :mod:`gyrodenoise.flightlog.formats` -- the registry of formats and the adapter interface; ``read_log``
* :mod:`gyrodenoise.flightlog.adapters` -- one adapter per format (sniff, read, messages, evidence, filtered copy)
* :mod:`gyrodenoise.flightlog.logdata` -- the per-format message decoders the adapters use
* :mod:`gyrodenoise.flightlog.autopilots` -- one strategy per autopilot (filter chain, stages, review rules, lines)

One log:

* :mod:`gyrodenoise.flightlog.engines` -- the native batch engine and the FogDenoiser FMU engine (fmpy)
* :mod:`gyrodenoise.flightlog.filtering` -- the streams through the filter; why a stream is left unfiltered
* :mod:`gyrodenoise.flightlog.checks` -- usable samples, the safety net on the output, gyro saturation
* :mod:`gyrodenoise.flightlog.report` -- the report of a stream (noise, motion kept) and its stderr lines
* :mod:`gyrodenoise.flightlog.output` -- the per-stream CSV and file names
* :mod:`gyrodenoise.flightlog.plotting` -- the stream plots, drawn inline or in forked helper processes
* :mod:`gyrodenoise.flightlog.spectra` -- the spectrum of a stream, for the report and its PNG
* :mod:`gyrodenoise.flightlog.pipeline` -- one log end to end (``process_log``)

Many logs, live links:

* :mod:`gyrodenoise.flightlog.cluster` -- one log as one task, on a Dask cluster or fsspec URLs; progress
* :mod:`gyrodenoise.flightlog.dispatch` -- many logs, serially, in a process pool or on a cluster (``process_many``)
* :mod:`gyrodenoise.flightlog.stopping` -- child processes, signals and partial files
* :mod:`gyrodenoise.flightlog.fleet` -- the fleet report from a run's summary
* :mod:`gyrodenoise.flightlog.live` -- live link forwarding, sample by sample
* :mod:`gyrodenoise.flightlog.process` -- the names above that the command line uses, in one place

The command: :mod:`gyrodenoise.cli.mavlink` (``gyrodenoise mavlink``).
"""
