"""Runs the add-on's unit tests under Blender's own Python (exit code 1 on failure).

    blender -b --factory-startup --python-exit-code 1 --python clients/blender/tests/run_unit_tests.py
"""

import os
import sys
import unittest

here = os.path.dirname(os.path.abspath(__file__))
suite = unittest.defaultTestLoader.discover(here, pattern="test_*.py", top_level_dir=here)
result = unittest.TextTestRunner(verbosity=2).run(suite)
print("%d passed, %d failed" % (result.testsRun - len(result.failures) - len(result.errors), len(result.failures) + len(result.errors)))
if not result.wasSuccessful():
    sys.exit(1)
