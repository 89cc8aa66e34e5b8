"""One log end to end, and many logs: the names of the bridge's processing in one place.

A re-export for the command line and the tests; each name lives in the module of
its concern (see :mod:`gyrodenoise.mavlink`): one log in
:mod:`gyrodenoise.mavlink.pipeline`, many logs in :mod:`gyrodenoise.mavlink.dispatch`,
the per-stream files in :mod:`gyrodenoise.mavlink.output`, the plots in
:mod:`gyrodenoise.mavlink.plotting`, the filtering in :mod:`gyrodenoise.mavlink.filtering`,
the checks in :mod:`gyrodenoise.mavlink.checks`, the stream reports in
:mod:`gyrodenoise.mavlink.report`, the log formats in :mod:`gyrodenoise.mavlink.formats`.
"""

from __future__ import annotations

from gyrodenoise.mavlink.checks import ABSURD_WORK, check_filtered, saturation, saturation_note
from gyrodenoise.mavlink.dispatch import expand_inputs, interrupted_summary, process_many
from gyrodenoise.mavlink.filtering import filter_form, filter_streams, not_filtered_reason
from gyrodenoise.mavlink.formats import LOG_SUFFIXES, log_kind
from gyrodenoise.mavlink.output import joined_time, safe_name, write_csv
from gyrodenoise.mavlink.pipeline import process_log
from gyrodenoise.mavlink.plotting import Plotter, plot_stream
from gyrodenoise.mavlink.report import MOTION_METRIC, log_problems, stream_report, streams_left_raw

#: the filtering step under the name the tests use
_filter_streams = filter_streams

__all__ = [
    "ABSURD_WORK", "LOG_SUFFIXES", "MOTION_METRIC", "Plotter", "check_filtered", "expand_inputs",
    "filter_form", "filter_streams", "interrupted_summary", "joined_time", "log_kind", "log_problems",
    "not_filtered_reason", "plot_stream", "process_log", "process_many", "safe_name", "saturation",
    "saturation_note", "stream_report", "streams_left_raw", "write_csv",
]
