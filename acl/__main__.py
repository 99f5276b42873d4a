import sys

from acl.cli import main

sys.exit(main())
