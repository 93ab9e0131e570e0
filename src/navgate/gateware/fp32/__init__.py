"""Float32 gateware cores (Amaranth 0.5 stream components).

Every core has a stream input ``i`` and output ``o``, a zero-argument
constructor with sensible defaults, ``LATENCY`` (cycles from input accepted to
output valid with no stalls) and ``THROUGHPUT`` (results per cycle), and is
checked bit for bit against ``navgate.numerics.fp32`` (tests/gateware/).
Architecture, latency and resources: docs/gateware-fp32.md.

``BLOCKS`` maps the block names used by the build flow to the classes of the pipelined
cores. The iterative (area-saving, one result per ``INTERVAL`` cycles) divider and square
root, :class:`Fp32DivIter` and :class:`Fp32SqrtIter`, are registered in
``navgate.hw.blocks.REGISTRY`` as ``fp32_div_iter`` and ``fp32_sqrt_iter``.
"""

from .add import Fp32Add
from .compare import Fp32Compare
from .convert import Fp32FromFixed, Fp32FromInt, Fp32ToFixed, Fp32ToInt
from .div import Fp32Div
from .div_iter import Fp32DivIter
from .mul import Fp32Mul
from .sqrt import Fp32Sqrt
from .sqrt_iter import Fp32SqrtIter

__all__ = [
    "BLOCKS",
    "Fp32Add",
    "Fp32Compare",
    "Fp32Div",
    "Fp32DivIter",
    "Fp32FromFixed",
    "Fp32FromInt",
    "Fp32Mul",
    "Fp32Sqrt",
    "Fp32SqrtIter",
    "Fp32ToFixed",
    "Fp32ToInt",
]

BLOCKS = {
    "fp32_add": Fp32Add,
    "fp32_mul": Fp32Mul,
    "fp32_div": Fp32Div,
    "fp32_sqrt": Fp32Sqrt,
    "fp32_compare": Fp32Compare,
    "fp32_from_int": Fp32FromInt,
    "fp32_to_int": Fp32ToInt,
    "fp32_from_fixed": Fp32FromFixed,
    "fp32_to_fixed": Fp32ToFixed,
}
