"""Budget arithmetic: from per-cycle simulation sums to fiscal-year gallons, taxes and ranges."""
