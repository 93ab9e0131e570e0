"""TF-Luna frame encoding and the UART source's byte plan and line transitions."""

import numpy as np

from navgate.devices import tfluna as L


def test_frame_layout_and_checksum():
    f = L.encode_frames([1.23], [1500], 30.0)[0].tolist()
    assert f[:2] == [0x59, 0x59]
    assert f[2] | (f[3] << 8) == 123 and f[4] | (f[5] << 8) == 1500
    assert (f[6] | (f[7] << 8)) / 8 - 256 == 30.0
    assert f[8] == sum(f[:8]) & 0xFF
    d = L.decode_frames(np.array([f]))
    assert d["checksum_ok"][0] and d["header_ok"][0] and d["reliable"][0]
    assert d["distance_m"][0] == 1.23


def test_strength_rule():
    assert L.strength_reliable([99, 100, 65534, 65535]).tolist() == [False, True, True, False]
    assert L.encode_frames([np.nan], [0])[0, 2] == 0  # no return: distance 0


def test_long_range_unit_fits_1500_m():
    f = L.encode_frames([1499.9], [500], unit_m=L.LONG_RANGE_UNIT_M)
    assert L.decode_frames(f, L.LONG_RANGE_UNIT_M)["distance_m"][0] == 1499.9


def test_fault_plan_and_expected_frames():
    frames = L.encode_frames(np.linspace(1, 2, 6), 1000)
    st = L.LidarStream(frames, {0: "bad_checksum", 1: "drop", 2: "truncate", 3: "noise",
                                4: "framing_error"}, seed=3)
    plan = st.byte_plan()
    assert plan[0][8][0] == (int(frames[0, 8]) + 1) & 0xFF
    assert plan[1] == [] and len(plan[2]) == 5
    assert len(plan[3]) == 12 and 0x59 in [b for b, _ in plan[3][:3]]
    assert plan[4][4][1] == 0 and len(plan[4]) == 9
    assert st.expected() == [3, 5]


def test_uart_transitions_8n1():
    tr, end = L.uart_transitions([(0x59, 1)], 0.0, 1.0)
    # start 0, then 0x59 = 1001 1010 LSB first: 1 0 0 1 1 0 1 0, stop 1
    levels = np.ones(10, int)
    for t, lv in tr:
        levels[int(t):] = lv
    assert levels.tolist() == [0, 1, 0, 0, 1, 1, 0, 1, 0, 1] and end == 10.0
