import sys

from neurotrajectory.cli import main

sys.exit(main())
