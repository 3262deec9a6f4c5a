#!/bin/bash
# The walk-run experiments of experiments/spinal/README.md (thesis 7.3.2), about 90 s each.
set -e
P=experiments/presets/plus_3fbl_walk.json
O=experiments/spinal/walkrun
./jg python -m jaxgait.spinal walkrun $P --out $O/a_default
./jg python -m jaxgait.spinal walkrun $P --drive A_INBAS=1:2 --drive A_INCPG=1:2 --out $O/b_A2
./jg python -m jaxgait.spinal walkrun $P --drive O_INBAS=0:0.1 --out $O/c_O_INBAS
./jg python -m jaxgait.spinal walkrun $P --drive A_INSEN=1:1.3 --out $O/d_A_INSEN
./jg python -m jaxgait.spinal walkrun $P --drive A_INBAS=1:1.6 --drive lean_offset=0:0.15 --out $O/e_lean
./jg python -m jaxgait.spinal walkrun experiments/presets/3fbl_walk.json --out $O/f_3fbl_fbl
