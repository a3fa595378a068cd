# SPDX-License-Identifier: Apache-2.0
"""Flips one bit at seeded random offsets of a bag, recovers each copy with
`tinyline bag recover`, and reads every output with the Python mcap reader
and its ROS 2 decoder. Recovery must never write a file an independent
reader refuses (damaged strings copied under fresh CRCs).

usage: recover_flips.py TINYLINE BAG FLIPS SEED WORKDIR
"""
import pathlib
import random
import subprocess
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def main() -> int:
    tinyline, bag, flips, seed, work = sys.argv[1], pathlib.Path(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), pathlib.Path(sys.argv[5])
    work.mkdir(parents=True, exist_ok=True)
    data = bag.read_bytes()
    rng = random.Random(seed)
    refused = []
    recovered = 0
    for i in range(flips):
        damaged = bytearray(data)
        at = rng.randrange(len(damaged))
        damaged[at] ^= 1 << rng.randrange(8)
        inp, out = work / 'in.mcap', work / 'out.mcap'
        inp.write_bytes(damaged)
        out.unlink(missing_ok=True)
        if subprocess.run([tinyline, 'bag', 'recover', str(inp), str(out)], capture_output=True).returncode != 0:
            continue  # a refusal with a reason is fine; a bad file is not
        recovered += 1
        try:
            with open(out, 'rb') as f:
                for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
                    pass
        except Exception as e:  # noqa: BLE001 - any refusal by the independent reader counts
            refused.append(f'bit flip at byte {at}: {type(e).__name__}: {str(e)[:160]}')
    for r in refused:
        print(r)
    print(f'{flips} flips of {bag.name}: {recovered} recovered, {len(refused)} refused by Python mcap')
    return 1 if refused else 0


if __name__ == '__main__':
    sys.exit(main())
