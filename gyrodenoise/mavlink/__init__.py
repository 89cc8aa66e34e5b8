"""MAVLink / DataFlash / ULog bridge of gyrodenoise.

Reads autopilot logs (telemetry ``.tlog``, ArduPilot DataFlash ``.bin``, PX4
``.ulg``) and live MAVLink links, finds every gyro stream, denoises each axis
with its own :class:`gyrodenoise.Denoiser`, and writes a filtered copy of the
log in which only the gyro fields of the IMU messages differ.

Modules:

* :mod:`gyrodenoise.mavlink.streams` -- the in-memory gyro stream, restart detection, noise figures
* :mod:`gyrodenoise.mavlink.dataflash` -- DataFlash ``.bin`` scanner / patcher (numpy, no per-message objects)
* :mod:`gyrodenoise.mavlink.tlog` -- telemetry-log framer, IMU decoding and re-packing (CRC checked)
* :mod:`gyrodenoise.mavlink.ulog` -- PX4 ULog via pyulog
* :mod:`gyrodenoise.mavlink.engines` -- the native batch engine and the FogDenoiser FMU engine (fmpy)
* :mod:`gyrodenoise.mavlink.process` -- one log end to end, and many logs in a process pool
* :mod:`gyrodenoise.mavlink.live` -- live link forwarding, sample by sample
* :mod:`gyrodenoise.cli.mavlink` -- the ``gyrodenoise mavlink`` command
"""
