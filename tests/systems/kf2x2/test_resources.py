"""Resource target of the seed-004 Kalman filter on the xc7z020 (navgate.hw.synth flow).

Cell counts from synthesis are exact for a given Yosys version, so they are asserted: at
N=20 the filter uses exactly 8 DSP48E1 (four 20x20 multipliers, two DSP48E1 each: 20 bits
exceed the 18-bit B port; multiplier 3 is (N+3) x (N+3) = 23 x 23 because the Goldschmidt
divider borrows it, which still fits two DSP48E1). The LUT/FF figures are only bounded
loosely (twice the measured 4125 / 2997) so that a regression that doubles them is caught.
"""

from navgate.hw.synth import synthesize
from navgate.hw.verilog import emit_verilog
from navgate.systems.kf2x2.top import Kf2x2


def test_kf2x2_n20_fits_eight_dsp48e1(tmp_path):
    use = synthesize(emit_verilog(Kf2x2(), "kf2x2"), "kf2x2", "xc7z020", tmp_path)
    assert use["dsp"] == 8
    assert use["bram36"] == 0
    assert use["lut"] < 8250 and use["ff"] < 6000
