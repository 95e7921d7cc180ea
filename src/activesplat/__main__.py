import sys

from activesplat.cli import main

sys.exit(main())
