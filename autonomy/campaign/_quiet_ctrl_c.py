"""Imported first by a local pool's fork server, which starts with Ctrl-C (SIGINT) held back
(:func:`autonomy.campaign.backends.start_fork_server`). From here on Ctrl-C is quiet in the
server and in the workers it forks: lander got the same Ctrl-C and says what is kept.

- The server, still importing the flight stack, ends at once: it has forked no worker yet.
- A worker flying a run takes it as Python's KeyboardInterrupt, which stops the run (lander
  records nothing for it); during the flight itself the runner's own handler stops it.
- A worker between runs (or still starting) ignores it: lander shuts the pool down. Raised
  there, outside any run, it was printed as the worker's traceback.
"""

import os
import signal

from autonomy.campaign import worker

_SERVER = os.getpid()


def _on_ctrl_c(signum, frame):
    if os.getpid() == _SERVER:
        os._exit(128 + signum)
    if worker.flying():
        signal.default_int_handler(signum, frame)


signal.signal(signal.SIGINT, _on_ctrl_c)
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
