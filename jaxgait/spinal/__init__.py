"""Layer 13: the spinal-network experiments (thesis ch. 6-7): record and analyse the IN_SEN
of a gait, build FBL-, 3FBL and 3FBL' from it, and the figures 7.1-7.4.

The network itself (interneurons, CPG, controller) is in :mod:`jaxgait.control`; this
package runs it.  Command line: ``python -m jaxgait.spinal`` (:mod:`jaxgait.spinal.cli`).
"""

from jaxgait.spinal.build import build_network, model_preset, select, select_walking
from jaxgait.spinal.record import Analysis, Record, SpinalError, analyse, record

__all__ = [
    "Analysis",
    "Record",
    "SpinalError",
    "analyse",
    "build_network",
    "model_preset",
    "record",
    "select",
    "select_walking",
]
