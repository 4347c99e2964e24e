"""ROS 2 (Jazzy) front end of the DiffAvatar asset service. Thin: everything it computes comes
from diffavatar_core; this package converts messages and runs jobs."""
