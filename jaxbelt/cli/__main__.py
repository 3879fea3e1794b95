"""``python -m jaxbelt.cli``: the same as the ``jaxbelt`` command."""

import sys

from . import main

sys.exit(main())
