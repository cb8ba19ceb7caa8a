"""PyTorch peer of host-train's matmul benchmark (`benches/matmul.rs`): the learner's layer
products (forward Y = X W^T, input gradient dX = dY W, weight gradient dW = dY^T X) at the
given shapes, on the CPU with a given thread count. Prints the median time of each as JSON.
"""
import argparse
import json

import torch

from learner_torch import timed


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--threads", type=int, required=True)
    p.add_argument("--reps", type=int, default=20)
    p.add_argument("--shape", action="append", required=True, help="m,k,n")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    out = []
    with torch.no_grad():
        for s in a.shape:
            m, k, n = (int(v) for v in s.split(","))
            x, w, dy = torch.randn(m, k), torch.randn(n, k), torch.randn(m, n)
            out.append({
                "shape": [m, k, n],
                "forward_s": timed(a.reps, lambda: x @ w.t()),
                "input_grad_s": timed(a.reps, lambda: dy @ w),
                "weight_grad_s": timed(a.reps, lambda: dy.t() @ x),
            })
    print(json.dumps({"torch": torch.__version__, "threads": a.threads, "results": out}))


if __name__ == "__main__":
    main()
