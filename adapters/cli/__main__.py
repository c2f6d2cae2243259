import sys

from adapters.cli.app import main

sys.exit(main())
