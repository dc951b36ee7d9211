"""mjnav: a MuJoCo mobile-robot navigation stack served over Zenoh.

The pure algorithm packages (``geometry``, ``motion``, ``mapping``, ``planning``, ``smoothing``, ``control``,
``estimation``, ``aerial``) depend on numpy/scipy/numba/osqp/casadi only; the I/O layers (``sim``, ``msgs``,
``bus``, ``runtime``, ``services``, ``viz``) wrap MuJoCo, ROS 2 CDR and Zenoh around them.
"""

from pathlib import Path

__version__ = "0.1.0"

#: Repository root when installed from a checkout (editable install); holds mjcf/ and services/.
REPO_ROOT = Path(__file__).resolve().parent.parent
