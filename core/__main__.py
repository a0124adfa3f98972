import sys

from hapticdesk.cli import main

sys.exit(main())
