import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))


def pytest_collection_modifyitems(config, items):
    """Run the tests marked ``long`` first (the order is otherwise kept): with pytest-xdist the workers then
    share out the short tests at the end instead of one of them finishing a long test alone."""
    items.sort(key=lambda item: item.get_closest_marker("long") is None)
