"""Chatter-aware lead/tilt planning for 5-axis ball-end milling (method.md §7).

Analysis: the engagement of a ball end mill at a posture
(:mod:`orient.engagement`), its process gain (:mod:`orient.gain`, errpred's
force model), the relative dynamics of tool and workpiece
(:mod:`orient.dynamics`, thin walls by finite elements in
:mod:`orient.workpiece_fem`), the zero-order and time-periodic stability
analyses (:mod:`orient.stability`). Decisions: the patent's strategies
(:mod:`orient.strategies`), the chatter detector (:mod:`orient.detect`) and
the posture memory (:mod:`orient.memory`). Planning along a CAM path with
FCL interference checks (:mod:`orient.plan`, :mod:`orient.interference`),
written through nc's writer (``python -m orient plan``).
"""

from orient.detect import ChatterDetector, Detection, DetectorSettings
from orient.dynamics import ModalSystem
from orient.engagement import LocalCut
from orient.gain import ProcessGain, process_gain, process_gain_batch
from orient.geometry import Posture, inclination, lead_tilt_of, posture_axis
from orient.interference import InterferenceChecker, ToolAssembly
from orient.memory import PostureMemory
from orient.plan import PlanResult, plan
from orient.scenario import PlanScenario, load_plan_scenario
from orient.stability import sdm_margin, stability_lobes, zoa_margin

__all__ = [
    "ChatterDetector", "Detection", "DetectorSettings", "InterferenceChecker", "LocalCut",
    "ModalSystem", "PlanResult", "PlanScenario", "Posture", "PostureMemory", "ProcessGain",
    "ToolAssembly", "inclination", "lead_tilt_of", "load_plan_scenario", "plan",
    "posture_axis", "process_gain", "process_gain_batch", "sdm_margin", "stability_lobes",
    "zoa_margin",
]
