"""The HTML report of a log written by a forked helper process, as the PNG plots are
(:class:`gyrodenoise.flightlog.plotting.Plotter`): the helper is started when the log's
processing starts and imports plotly and :mod:`gyrodenoise.flightlog.html_report`
while the log is read and filtered; at the end it is handed the report and the
arrays (:meth:`HtmlWriter.write`) and draws the page while the rest of the outputs
are finished; :meth:`HtmlWriter.close` waits for it. Elsewhere than Linux (no fork)
the page is written in this process.
"""

from __future__ import annotations

import sys

from gyrodenoise.flightlog.stopping import as_child, signals_blocked, stop_processes


def _write(path, report, series):
    from gyrodenoise.flightlog.html_report import write_log_report
    write_log_report(path, report, series)


def _helper(conn):
    """The helper's loop: import, then write each ``(path, report, series)`` it is sent,
    answering "" or the error's text; ``None`` ends it."""
    as_child()          # SIGINT ignored, SIGTERM unblocked, ends with its parent (the parent stops it)
    try:
        import plotly.graph_objects  # noqa: F401 - imported ahead, while the parent reads the log
        import plotly.subplots  # noqa: F401
        import gyrodenoise.flightlog.html_report  # noqa: F401
    except ImportError:
        pass
    while True:
        try:
            job = conn.recv()
        except EOFError:
            break
        if job is None:
            break
        try:
            _write(*job)
            conn.send("")
        except Exception as exc:  # noqa: BLE001 - the parent reports it
            conn.send(f"HTML report {job[0]}: {type(exc).__name__}: {exc}")


class HtmlWriter:
    """Writes one log's HTML report, in a forked helper when ``background`` (Linux)."""

    def __init__(self, background=True):
        self.proc = self.conn = self.sender = None
        self.pending = 0
        if background and sys.platform.startswith("linux"):
            import multiprocessing as mp
            ctx = mp.get_context("fork")
            self.conn, child = ctx.Pipe()
            self.proc = ctx.Process(target=_helper, args=(child,), daemon=True)
            with signals_blocked():
                self.proc.start()
            child.close()

    def write(self, path, report, series):
        """Write (or hand to the helper) the report of ``report`` and ``series``
        (:func:`gyrodenoise.flightlog.html_report.write_log_report`) to ``path``."""
        if self.proc is None:
            _write(path, report, series)
            return
        import threading
        # a thread sends: a send blocks until the helper reads, and the helper may
        # still be importing (the arrays are MBs)
        self.sender = threading.Thread(target=self._send, args=((str(path), report, series),), daemon=True)
        self.sender.start()
        self.pending += 1

    def _send(self, job):
        try:
            self.conn.send(job)
        except (OSError, ValueError):          # the helper was stopped (an interrupt)
            pass

    def close(self):
        """Wait for the helper's page; RuntimeError with its failure."""
        if self.proc is None:
            return
        errors = []
        try:
            if self.sender is not None:
                self.sender.join()
            for _ in range(self.pending):
                r = self.conn.recv()
                if r:
                    errors.append(r)
            self.conn.send(None)
        except (EOFError, OSError):
            errors.append("HTML report helper process ended unexpectedly")
        except BaseException:
            self.abort()
            raise
        self.proc.join(timeout=30)
        if self.proc.is_alive():
            self.proc.terminate()
        self.proc = None
        if errors:
            raise RuntimeError(errors[0])

    def abort(self):
        """Stop the helper at once (an interrupt or a failure)."""
        if self.proc is not None:
            stop_processes([self.proc])
            self.conn.close()
            self.proc = None
