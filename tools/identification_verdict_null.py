"""How often the per-axis verdict fails a perfect model (issue 37): records drawn from a known
profile are identified with the defaults and compared with their own profile's emulated
records, exactly as tools/identification_real_records.py does with a real record; a failing
axis here is the criterion's own false-failure rate, since the truth is in the model class.

    python tools/identification_verdict_null.py PROFILE --samples 44930 --rate 100 --records 30
    python tools/identification_verdict_null.py PROFILE --samples 1000000 --rate 100 --records 8

PROFILE is a profile file (e.g. the one identification_real_records.py --profile-dir writes
for a real record); a path that is absent is skipped with a line saying so. Prints, after each
record, how many axes failed the ADEV forward check (emulated median inside the record's 95 %
band at >= 97 % of octave taus 0.2 s .. L/10), the reverse check (the record inside the
emulated 2.5-97.5 % range at >= 95 %), and either.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("profile", type=Path)
    parser.add_argument("--samples", type=int, required=True)
    parser.add_argument("--rate", type=float, required=True)
    parser.add_argument("--records", type=int, default=10)
    parser.add_argument("--seeds", type=int, default=40, help="emulated records per verdict")
    parser.add_argument("--first-seed", type=int, default=5000)
    args = parser.parse_args(argv)
    if not args.profile.exists():
        print(f"{args.profile}: absent, skipped")
        return 0
    from bmg160_emu.noise.identify import identify
    from bmg160_emu.noise.profile import load_profile
    from bmg160_emu.noise.sensor_noise import profile_noise
    from bmg160_emu.noise.verdict import ADEV_FORWARD, ADEV_REVERSE, compare_profile

    truth = load_profile(str(args.profile))
    forward = reverse = either = axes = 0
    for r in range(args.records):
        data = profile_noise(truth, args.rate, seed=args.first_seed + r).generate(args.samples)
        result = identify(data, args.rate)
        verdict = compare_profile(data, args.rate, result.to_profile("null"), args.seeds)
        for a in verdict.axes:
            axes += 1
            f, v = a.adev_forward < ADEV_FORWARD, a.adev_reverse < ADEV_REVERSE
            forward, reverse, either = forward + f, reverse + v, either + (f or v)
        print(f"record {r + 1}: of {axes} axes, {forward} fail forward, {reverse} reverse, "
              f"{either} either ({either / axes:.0%})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
