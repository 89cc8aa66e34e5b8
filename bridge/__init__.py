"""MAVLink / DataFlash / ULog bridge of gyrodenoise.

Reads autopilot logs (telemetry ``.tlog``, ArduPilot DataFlash ``.bin``, PX4
``.ulg``) and live MAVLink links, finds every gyro stream, denoises each axis
with its own :class:`gyrodenoise.Denoiser`, and writes a filtered copy of the
log in which only the gyro fields of the IMU messages differ.

Modules:

* :mod:`bridge.streams` -- the in-memory gyro stream, restart detection, noise figures
* :mod:`bridge.dataflash` -- DataFlash ``.bin`` scanner / patcher (numpy, no per-message objects)
* :mod:`bridge.tlog` -- telemetry-log framer, IMU decoding and re-packing (CRC checked)
* :mod:`bridge.ulog` -- PX4 ULog via pyulog
* :mod:`bridge.engines` -- the native batch engine and the FogDenoiser FMU engine (fmpy)
* :mod:`bridge.process` -- one log end to end, and many logs in a process pool
* :mod:`bridge.live` -- live link forwarding, sample by sample
* :mod:`bridge.cli` -- the ``gyrodenoise mavlink`` command
"""
