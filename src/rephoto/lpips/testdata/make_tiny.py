#!/usr/bin/python3
"""Writes the tiny torch.save files torch_file_test.cc reads (Debian python3-torch 1.13):
tiny_zip.pth (zip format) and tiny_legacy.pth (legacy format), each an OrderedDict
{'w': 2x3 float tensor viewed through a transpose (strides (1, 2)) of a 6-element storage,
 'b': 3 float values at storage offset 1 of a 4-element storage, 'n': int64 scalar}."""
import collections
import torch

w = torch.arange(6, dtype=torch.float32).view(3, 2).t()  # values [[0,2,4],[1,3,5]]
base = torch.tensor([9.0, 0.5, -1.5, 2.25])
b = base[1:]
state = collections.OrderedDict([("w", w), ("b", b), ("n", torch.tensor(7))])
torch.save(state, "tiny_zip.pth")
torch.save(state, "tiny_legacy.pth", _use_new_zipfile_serialization=False)
