"""Writes lecroy_seq_hifirst_byte.trc: a 3-segment sequence, 8-bit codes (COMM_TYPE 0), big endian
(HIFIRST), with USER_TEXT and a TRIGTIME array, packed field by field from the LECROY_2_3 template
(instruments.md section 2.6) with Python's struct, independently of radbench's own writer.
tests/trc_golden.rs checks radbench's reading of it; lecroyparser reads the same volts.

Run: python3 tests/data/make_golden_trc.py (writes next to this script).
"""

import pathlib
import struct

ORDER = ">"  # HIFIRST
SEGMENTS = [(0.0, -2.0e-9), (1.0e-3, -1.75e-9), (2.5e-3, -2.25e-9)]
CODES = [-128, -1, 0, 127, 1, 2, 3, 4, -5, -6, -7, -8]
USER_TEXT = b"golden\x00\x00"


def field(buf, offset, fmt, value):
    struct.pack_into(ORDER + fmt, buf, offset, value)


desc = bytearray(346)
desc[0:8] = b"WAVEDESC"
desc[16:26] = b"LECROY_2_3"
field(desc, 32, "h", 0)  # COMM_TYPE byte
field(desc, 34, "h", 0)  # COMM_ORDER HIFIRST
field(desc, 36, "i", 346)  # WAVE_DESCRIPTOR
field(desc, 40, "i", len(USER_TEXT))
field(desc, 48, "i", 16 * len(SEGMENTS))  # TRIGTIME_ARRAY
field(desc, 60, "i", len(CODES))  # WAVE_ARRAY_1 bytes
desc[76:90] = b"LECROYWR8208HD"
field(desc, 92, "i", 4242)
desc[96:101] = b"probe"
field(desc, 116, "i", len(CODES))  # WAVE_ARRAY_COUNT
field(desc, 120, "i", 4)
field(desc, 128, "i", len(CODES) - 1)
field(desc, 136, "i", 1)
field(desc, 144, "i", len(SEGMENTS))  # SUBARRAY_COUNT
field(desc, 148, "i", 1)
field(desc, 156, "f", 0.01)  # VERTICAL_GAIN
field(desc, 160, "f", 0.5)  # VERTICAL_OFFSET
field(desc, 172, "h", 8)
field(desc, 174, "h", len(SEGMENTS))
field(desc, 176, "f", 1.0e-9)  # HORIZ_INTERVAL
field(desc, 180, "d", -2.0e-9)  # HORIZ_OFFSET
desc[196:197] = b"V"
desc[244:245] = b"S"
struct.pack_into(ORDER + "dBBBBhh", desc, 296, 59.5, 59, 23, 29, 2, 2024, 0)  # TRIGGER_TIME
field(desc, 316, "h", 0)  # RECORD_TYPE single_sweep
field(desc, 326, "h", 2)  # VERT_COUPLING DC_1MOhm
field(desc, 328, "f", 10.0)  # PROBE_ATT
field(desc, 344, "h", 3)  # WAVE_SOURCE C4

block = bytes(desc) + USER_TEXT
block += b"".join(struct.pack(ORDER + "dd", t, o) for t, o in SEGMENTS)
block += struct.pack(f"{len(CODES)}b", *CODES)
out = pathlib.Path(__file__).with_name("lecroy_seq_hifirst_byte.trc")
out.write_bytes(b"#9%09d" % len(block) + block)
print(out, len(block) + 11, "bytes")
