#!/usr/bin/env python3
"""Independent reference for rephoto's seeded splits (src/rephoto/split/random.h, split.cc).

SplitMix64 as in Vigna's splitmix64.c, unbiased bounded integers by rejection of draws below
2^64 mod bound, Fisher-Yates from the last element. Prints the expected test sets that
split_test.cc checks (run: /usr/bin/python3 make_split_fixture.py).
"""

import math

M = (1 << 64) - 1


class SplitMix64:
    def __init__(self, seed):
        self.state = seed & M

    def next(self):
        self.state = (self.state + 0x9E3779B97F4A7C15) & M
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M
        return z ^ (z >> 31)

    def uniform_below(self, bound):
        threshold = (1 << 64) % bound
        while True:
            r = self.next()
            if r >= threshold:
                return r % bound


def shuffle(items, seed):
    rng = SplitMix64(seed)
    items = list(items)
    for i in range(len(items), 1, -1):
        j = rng.uniform_below(i)
        items[i - 1], items[j] = items[j], items[i - 1]
    return items


def kfold(names, k, seed):
    names = sorted(names)
    order = shuffle(range(len(names)), seed)
    folds = [[] for _ in range(k)]
    for position, index in enumerate(order):
        folds[position % k].append(names[index])
    return [sorted(f) for f in folds]


def fraction(names, f, seed):
    names = sorted(names)
    count = min(max(math.floor(f * len(names) + 0.5), 1), len(names) - 1)  # half away from 0
    order = shuffle(range(len(names)), seed)
    return sorted(names[i] for i in order[:count])


if __name__ == "__main__":
    names = [f"img{i:02d}.png" for i in range(10)]
    print("shuffle(range(10), 42):", shuffle(range(10), 42))
    print("kfold:3:42 test sets:", kfold(names, 3, 42))
    print("fraction:0.3:7 test set:", fraction(names, 0.3, 7))
