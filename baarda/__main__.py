import sys

from baarda.cli import main

sys.exit(main())
