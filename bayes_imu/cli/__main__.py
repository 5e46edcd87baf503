"""``python -m bayes_imu.cli``: the ``bayes-imu`` command."""

import sys

from .main import main

sys.exit(main())
