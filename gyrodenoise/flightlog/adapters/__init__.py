"""One adapter per log format (the interface: :mod:`gyrodenoise.flightlog.formats`)."""
