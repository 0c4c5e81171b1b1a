"""The studies behind the scripts: the comparison (training, evaluation, tuning, residual agents,
sizing), the numerics and stiff-case reports, the reliability suite and the benchmarks."""

import warnings

# The studies run earlier versions of a task on purpose (the compared version, the protocol ids, agents of the version
# they were trained on): Gymnasium's notice that a newer version is registered says nothing to them. It is silenced
# for the mbs_envs ids in a program that imports the studies; elsewhere Gymnasium shows it as usual.
warnings.filterwarnings(
    "ignore", message=r".*The environment mbs_envs/\w+-v\d+ is out of date", category=DeprecationWarning
)
