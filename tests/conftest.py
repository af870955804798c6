"""Suite-wide set-up.

The tests that press Ctrl-C stand in for a user at a terminal, where SIGINT reaches the
program. A suite started as a script's background job (``.ci/run &`` in a non-interactive
shell, ``nohup``) inherits SIGINT ignored, and so would every program it starts: the
scanner rightly leaves an ignored SIGINT ignored (headless.lifecycle.StopRequests.install).
So the suite takes SIGINT back as Python's default, which its children then inherit as the
system's default.
"""

import signal

if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
