import sys

from contactvisco.cli import main

sys.exit(main())
