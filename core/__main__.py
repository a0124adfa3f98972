import sys

from hapticdesk.cli import entry

sys.exit(entry())
