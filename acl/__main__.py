"""`python -m acl`: the command line (acl.cli)."""
import signal
import sys

# Until acl.cli.main installs its handlers, an interrupt ends the process quietly: nothing is written yet.
signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))

from acl.cli import main  # noqa: E402

sys.exit(main())
