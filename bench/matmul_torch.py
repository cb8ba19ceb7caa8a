"""PyTorch peer of host-train's matmul benchmark (`benches/matmul.rs`): the learner's layer
products (forward Y = X W^T, input gradient dX = dY W, weight gradient dW = dY^T X) at the
given shapes, on the CPU with a given thread count. Prints the median time of each as JSON.
"""
import argparse
import json
import time

import torch


def median_time(f, reps):
    f()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    times.sort()
    return times[len(times) // 2]


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
                "forward_s": median_time(lambda: x @ w.t(), a.reps),
                "input_grad_s": median_time(lambda: dy @ w, a.reps),
                "weight_grad_s": median_time(lambda: dy.t() @ x, a.reps),
            })
    print(json.dumps({"torch": torch.__version__, "threads": a.threads, "results": out}))


if __name__ == "__main__":
    main()
