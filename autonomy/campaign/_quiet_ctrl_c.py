"""Imported first by a local pool's fork server, which starts with Ctrl-C (SIGINT) held back
(:func:`autonomy.campaign.backends.start_fork_server`): from here on a Ctrl-C while the
server is still importing the flight stack ends it quietly, without a traceback; ``lander``
got the same Ctrl-C and says what is kept. The workers forked from the server keep this
handler, where it is Python's usual KeyboardInterrupt."""

import os
import signal

_SERVER = os.getpid()


def _on_ctrl_c(signum, frame):
    if os.getpid() == _SERVER:
        os._exit(128 + signum)  # nothing to save: the server has forked no worker yet
    signal.default_int_handler(signum, frame)


signal.signal(signal.SIGINT, _on_ctrl_c)
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
