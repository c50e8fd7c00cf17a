"""Broken plugins, one failure each (tests/e2e/test_isolation.py): none of them may stop
hnnbench, or any other plugin, command or job."""
