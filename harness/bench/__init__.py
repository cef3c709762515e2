"""Benchmarks of component alternatives on identical inputs (``monorarp bench ...``)."""
