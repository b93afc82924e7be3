"""HDR uplift (GaSLight section 3.1): give every photo unclipped radiance.

* :mod:`.merge` - Debevec log-domain merge with the paper's weights;
* :mod:`.recursive` - recursive 2 EV exposure prediction until nothing clips;
* :mod:`.predictors` - the predictor interface and registry (``fast``,
  ``diffusion``, ``oracle``, ``reexpose``);
* :mod:`.bracket` - real exposure brackets: grouping, response, alignment;
* :mod:`.panorama` - lat-long photos uplifted face by face on a cube;
* :mod:`.pipeline` - photo set -> HDR views (used by the converters).

The fast predictor's calibration and the uplift bench's extra methods are
measurement code: :mod:`gaslight_usd.bench.calibrate`, :mod:`gaslight_usd.bench.uplift_methods`.
"""

from .curves import GAMMA22, SRGB, Curve, curve_by_name, input_transform
from .merge import merge_stack, stack_weights
from .predictors import Predictor, available_predictors, get_predictor, register_predictor
from .recursive import UpliftResult, uplift_recursive

__all__ = ["GAMMA22", "SRGB", "Curve", "Predictor", "UpliftResult", "available_predictors",
           "curve_by_name", "get_predictor", "input_transform", "merge_stack",
           "register_predictor", "stack_weights", "uplift_recursive"]
