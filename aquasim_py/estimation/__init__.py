"""Pure estimation maths: filters, least squares, bounds, particle filters (no SimPy)."""
