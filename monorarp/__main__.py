import sys

from monorarp.cli import main

sys.exit(main())
