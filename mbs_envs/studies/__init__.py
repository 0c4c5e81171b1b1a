"""The studies behind the scripts: the comparison (training, evaluation, tuning, residual agents,
sizing), the numerics and stiff-case reports, the reliability suite and the benchmarks."""
