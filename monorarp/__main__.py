import sys

from monorarp.app.cli import main

sys.exit(main())
