"""One log end to end, and many logs: the names of the bridge's processing in one place.

A re-export for the command line and the tests; each name lives in the module of
its concern (see :mod:`gyrodenoise.flightlog`): one log in
:mod:`gyrodenoise.flightlog.pipeline`, many logs in :mod:`gyrodenoise.flightlog.dispatch`,
the per-stream files in :mod:`gyrodenoise.flightlog.output`, the plots in
:mod:`gyrodenoise.flightlog.plotting`, the filtering in :mod:`gyrodenoise.flightlog.filtering`,
the checks in :mod:`gyrodenoise.flightlog.checks`, the stream reports in
:mod:`gyrodenoise.flightlog.report`, the log formats in :mod:`gyrodenoise.flightlog.formats`.
"""

from __future__ import annotations

from gyrodenoise.flightlog.checks import ABSURD_WORK, check_filtered, saturation, saturation_note
from gyrodenoise.flightlog.dispatch import expand_inputs, interrupted_summary, process_many
from gyrodenoise.flightlog.filtering import filter_form, filter_streams, not_filtered_reason
from gyrodenoise.flightlog.formats import LOG_SUFFIXES, log_format
from gyrodenoise.flightlog.output import joined_time, safe_name, write_csv
from gyrodenoise.flightlog.pipeline import process_log
from gyrodenoise.flightlog.plotting import Plotter, plot_stream
from gyrodenoise.flightlog.report import MOTION_METRIC, log_problems, stream_report, streams_left_raw

#: the filtering step under the name the tests use
_filter_streams = filter_streams

__all__ = [
    "ABSURD_WORK", "LOG_SUFFIXES", "MOTION_METRIC", "Plotter", "check_filtered", "expand_inputs",
    "filter_form", "filter_streams", "interrupted_summary", "joined_time", "log_format", "log_problems",
    "not_filtered_reason", "plot_stream", "process_log", "process_many", "safe_name", "saturation",
    "saturation_note", "stream_report", "streams_left_raw", "write_csv",
]
