"""Decoder-aware code search: the codes the decoder turns back into the state, not only the codes nearest to the
encoder's vectors.

The paper encodes a state by snapping each of the N x K encoder group vectors to its nearest code (cosine). That
snapping is most of a trained model's error (`experiments/error_split.py`): the decoder fed the unsnapped vectors
errs 2-4x less. This module keeps the model and the token interface as they are and changes only how codes are
picked: starting from the nearest codes, it runs coordinate descent on the decoder linearised around them,

    x_hat(codes') ~= x_hat(codes) + sum_{n,k} J_n W_k (e_{k, codes'[n,k]} - e_{k, codes[n,k]})

with J_n the decoder's Jacobian for its input token n, W_k the quantiser's output projection of group k and
e_{k,s} the unit-norm codes. A sweep visits the N*K positions in turn and gives each the code that minimises the
linearised squared error (radians, active DoFs). A round ends with an exact decode; a row keeps the codes it
started the round with unless the exact error went down, so the search never makes a row worse on its
objective. Same tokens, same decoder: analysis by synthesis, as speech codecs pick their codebook entries (CELP).

Cost: per round one Jacobian (a backward pass through one copy of the batch per active DoF) and N*K*sweeps small
steps. For the `small` preset, 2 rounds x 2 sweeps, one CPU thread (`benchmarks/bench_processor.py --search_rounds
2`, two 6-DoF Inspire hands): 1.4 ms per hand-row at batch 256 and 14 ms per frame at batch 1, against 0.08 and
1.1 ms for the nearest codes; hands with more DoFs cost more (the card's 14 hands: 2.9 ms per row on average).
"""

import torch

CHUNK_ROWS = 128  # rows per Jacobian batch: 22 x 128 decoder rows at a time bounds the memory


def decoder_jacobian(model, zq: torch.Tensor, cond: torch.Tensor, outputs: torch.Tensor) -> torch.Tensor:
    """(B, N, C) decoder inputs, (B, C) hand conditions, (J,) output DoFs -> (B, J, N, C) d x_hat_rad[:, outputs] / d zq
    (one backward pass through J copies of the batch)."""
    b, j = zq.shape[0], len(outputs)
    # also under torch.inference_mode (a policy's select_action): the copies made here are normal tensors
    with torch.inference_mode(False), torch.enable_grad():
        z = zq.detach().clone().repeat(j, 1, 1).requires_grad_(True)  # (J B, N, C): copy i of each row, output i
        out = model._decode_latent(z, cond.detach().clone().repeat(j, 1)).view(j, b, -1)  # (J, B, 22) radians
        index = outputs.clone().view(j, 1, 1).expand(j, b, 1)  # (J, B, 1)
        picked = out.gather(2, index)  # (J, B, 1): output outputs[i] of copy i
        (grad,) = torch.autograd.grad(picked.sum(), z)  # (J B, N, C)
    return grad.view(j, b, *zq.shape[1:]).transpose(0, 1)  # (B, J, N, C)


@torch.no_grad()
def search_codes(
    model,
    states_rad: torch.Tensor,
    codes: torch.Tensor,
    cond: torch.Tensor,
    mask: torch.Tensor | None = None,
    rounds: int = 1,
    sweeps: int = 2,
) -> torch.Tensor:
    """Refine (B, N, K) codes of (B, 22) states; `cond` (B, C) the hand conditions, `mask` (B, 22) the active DoFs
    (None = all 22; a row without any keeps its codes). Returns new (B, N, K) int64 codes, each row's exact error
    <= that of `codes`."""
    if rounds < 0 or sweeps < 1:
        raise ValueError(f"code search needs rounds >= 0 and sweeps >= 1, got rounds={rounds}, sweeps={sweeps}")
    weight = torch.ones_like(states_rad) if mask is None else mask.to(states_rad.dtype)  # (B, 22)
    if rounds == 0 or not bool(weight.any()):
        return codes
    parts = [
        _search_chunk(model, states_rad[i : i + CHUNK_ROWS], codes[i : i + CHUNK_ROWS], cond[i : i + CHUNK_ROWS],
                      weight[i : i + CHUNK_ROWS], rounds, sweeps)  # fmt: skip
        for i in range(0, len(codes), CHUNK_ROWS)
    ]
    return torch.cat(parts)


def _search_chunk(model, x, codes, cond, weight, rounds: int, sweeps: int) -> torch.Tensor:
    vq = model.quantizer
    n_tok, n_grp = codes.shape[1:]
    cb = vq.normalized_codebooks()  # (K, S, d)
    proj = vq.project_out.weight.view(-1, n_grp, vq.group_dim)  # (C, K, d)
    rows = torch.arange(len(x), device=x.device)  # (B,)
    dofs = weight.any(0).nonzero().flatten()  # (J,) DoFs active in any row: the only outputs that count
    x, weight = x[:, dofs], weight[:, dofs]  # (B, J)
    codes = codes.long()
    for _ in range(rounds):
        zq = vq.get_output_from_indices(codes)  # (B, N, C)
        x_hat = model._decode_latent(zq, cond)[:, dofs]  # (B, J)
        start_err = (((x_hat - x) * weight) ** 2).sum(-1)  # (B,)
        jac = decoder_jacobian(model, zq, cond, dofs)  # (B, J, N, C)
        # effect on x_hat of every code at every position, relative to the current code: (B, N, K, S, J)
        gain = torch.einsum("bjnc,ckd->bnkjd", jac, proj)  # (B, N, K, J, d)
        effect = torch.einsum("bnkjd,ksd->bnksj", gain, cb)  # (B, N, K, S, J)
        current = torch.gather(effect, 3, codes[..., None, None].expand(-1, -1, -1, 1, effect.shape[-1]))
        effect = (effect - current) * weight[:, None, None, None, :]  # (B, N, K, S, J)
        residual = (x - x_hat) * weight  # (B, J) what the changes should add
        chosen = codes.clone()  # (B, N, K)
        for _ in range(sweeps):
            for n in range(n_tok):
                for k in range(n_grp):
                    options = effect[:, n, k]  # (B, S, J)
                    freed = residual + options[rows, chosen[:, n, k]]  # (B, J) residual without this position
                    best = ((freed.unsqueeze(1) - options) ** 2).sum(-1).argmin(1)  # (B,)
                    chosen[:, n, k] = best
                    residual = freed - options[rows, best]
        x_new = model._decode_latent(vq.get_output_from_indices(chosen), cond)[:, dofs]  # (B, J)
        new_err = (((x_new - x) * weight) ** 2).sum(-1)  # (B,)
        codes = torch.where((new_err < start_err)[:, None, None], chosen, codes)  # (B, N, K)
    return codes
