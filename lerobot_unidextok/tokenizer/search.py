"""Decoder-aware code search: the codes the decoder turns back into the state, not only the codes nearest to the
encoder's vectors.

The paper encodes a state by snapping each of the N x K encoder group vectors to its nearest code (cosine). That
snapping is most of a trained model's error (`experiments/error_split.py`): the decoder fed the unsnapped vectors
errs 2-4x less. This module keeps the model and the token interface as they are and changes only how codes are
picked: starting from the nearest codes, it descends on the decoder linearised around them,

    x_hat(codes') ~= x_hat(codes) + sum_{n,k} J_n W_k (e_{k, codes'[n,k]} - e_{k, codes[n,k]})

with J_n the decoder's Jacobian for its input token n, W_k the quantiser's output projection of group k and
e_{k,s} the unit-norm codes, minimising the linearised squared error (radians, active DoFs). A round ends with an
exact decode; a row keeps the codes it started the round with unless the exact error went down, so the search
never makes a row worse on its objective. Same tokens, same decoder: analysis by synthesis, as speech codecs pick
their codebook entries (CELP).

Two ways to move through the codes, both on the same linearisation and with the same exact check per round:
- `EncodingConfig(method="sweeps")` (`search_codes`, the first one; checkpoints written before the search had a
  method use it): coordinate descent, each sweep gives each of the N*K positions in turn its best code; N*K*sweeps small
  sequential steps per round.
- `EncodingConfig(method="greedy")` (`greedy_codes`): each step scores every single change (all N*K positions x S codes at
  once) and makes the best one, up to `changes` steps per round, stopping early when no row gains. About as accurate
  per round and cheaper: the few changes that matter (a round changes a quarter of the positions) instead of
  N*K sequential steps, and the decoder's forward pass for the Jacobian also gives the round's start. A row
  whose error is within `tolerance_deg` after a round leaves the search (early exit), so later rounds,
  each a Jacobian, cost only for the rows that need them.

Cost: per round one Jacobian (a backward pass through one copy of the batch per active DoF), which dominates at
large batches; at batch 1 the per-step overhead counts too. Measured against the nearest codes in
`benchmarks/bench_processor.py --encodings` (docs/tokenizer.md "Code search").
"""

import torch

CHUNK_ROWS = 128  # rows per Jacobian batch: 22 x 128 decoder rows at a time bounds the memory


def decoder_jacobian(model, zq: torch.Tensor, cond: torch.Tensor, outputs: torch.Tensor) -> torch.Tensor:
    """(B, N, C) decoder inputs, (B, C) hand conditions, (J,) output DoFs -> (B, J, N, C) d x_hat_rad[:, outputs] / d zq
    (one backward pass through J copies of the batch)."""
    return decoded_and_jacobian(model, zq, cond, outputs)[1]


def decoded_and_jacobian(
    model, zq: torch.Tensor, cond: torch.Tensor, outputs: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """`decoder_jacobian` and the states the codes decode to, from the same forward pass: ((B, 22) x_hat_rad,
    (B, J, N, C))."""
    b, j = zq.shape[0], len(outputs)
    # also under torch.inference_mode (a policy's select_action): the copies made here are normal tensors
    with torch.inference_mode(False), torch.enable_grad():
        z = zq.detach().clone().repeat(j, 1, 1).requires_grad_(True)  # (J B, N, C): copy i of each row, output i
        out = model._decode_latent(z, cond.detach().clone().repeat(j, 1)).view(j, b, -1)  # (J, B, 22) radians
        index = outputs.clone().view(j, 1, 1).expand(j, b, 1)  # (J, B, 1)
        picked = out.gather(2, index)  # (J, B, 1): output outputs[i] of copy i
        (grad,) = torch.autograd.grad(picked.sum(), z)  # (J B, N, C)
    x_hat = out[0].detach().clone()  # (B, 22): every copy decodes the same codes
    return x_hat, grad.view(j, b, *zq.shape[1:]).transpose(0, 1)  # (B, 22), (B, J, N, C)


def _chunks(fn, model, states_rad, codes, cond, mask, rounds: int, per_round: int):
    """Run `fn` over CHUNK_ROWS rows at a time after the checks both searches share; None when there is nothing
    to search (no rounds, no active DoF)."""
    weight = torch.ones_like(states_rad) if mask is None else mask.to(states_rad.dtype)  # (B, 22)
    if rounds == 0 or not bool(weight.any()):
        return None
    parts = [fn(model, states_rad[i : i + CHUNK_ROWS], codes[i : i + CHUNK_ROWS], cond[i : i + CHUNK_ROWS],
                weight[i : i + CHUNK_ROWS], rounds, per_round)  # fmt: skip
             for i in range(0, len(codes), CHUNK_ROWS)]
    return tuple(torch.cat(p) for p in zip(*parts, strict=True)) if isinstance(parts[0], tuple) else torch.cat(parts)


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
    found = _chunks(_search_chunk, model, states_rad, codes, cond, mask, rounds, sweeps)
    return codes if found is None else found


@torch.no_grad()
def greedy_codes(
    model,
    states_rad: torch.Tensor,
    codes: torch.Tensor,
    cond: torch.Tensor,
    mask: torch.Tensor | None = None,
    rounds: int = 1,
    changes: int = 16,
    tolerance_rad: float = 0.0,
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Like `search_codes`, moving by best single changes: per round up to `changes` steps, each making the one
    change of one position's code that lowers the linearised error most (per row; a row stops when none does).
    After a round, a row whose exact mean absolute error over its active DoFs is at most `tolerance_rad` leaves
    the search (early exit: the later rounds, each a Jacobian, run on the rows still above it; 0 = every row runs
    every round). Returns new (B, N, K) int64 codes, each row's exact error <= that of `codes`, and (B, 22) the
    states they decode to, radians (the rounds' exact decodes: no second pass; None when nothing was searched)."""
    if rounds < 0 or changes < 1 or tolerance_rad < 0:
        raise ValueError(f"code search needs rounds >= 0, changes >= 1 and tolerance >= 0, got rounds={rounds}, "
                         f"changes={changes}, tolerance_rad={tolerance_rad}")  # fmt: skip
    found = _chunks(_greedy_chunk, model, states_rad, codes, cond, mask, rounds, (changes, tolerance_rad))
    return (codes, None) if found is None else found


def code_effects(model) -> torch.Tensor:
    """(C, K S): the decoder input added by each code of each group (the quantiser's output projection of the
    unit-norm codes), so that d zq = effects[:, k S + s'] - effects[:, k S + s] when group k's code s becomes s'."""
    vq = model.quantizer
    proj = vq.project_out.weight.view(-1, vq.num_groups, vq.group_dim)  # (C, K, d)
    return torch.einsum("ckd,ksd->cks", proj, vq.normalized_codebooks()).flatten(1)  # (C, K S)


def _greedy_chunk(
    model, x, codes, cond, weight, rounds: int, per_round: tuple[int, float]
) -> tuple[torch.Tensor, torch.Tensor]:
    changes, tolerance_rad = per_round
    dofs = weight.any(0).nonzero().flatten()  # (J,) DoFs active in any row
    x_active, weight = x[:, dofs], weight[:, dofs]  # (B, J)
    codes, decoded = codes.long().clone(), None  # (B, N, K), filled in per round
    todo = torch.arange(len(x), device=x.device)  # (T,) rows still searched
    for _ in range(rounds):
        new_codes, new_decoded = _greedy_round(model, x_active[todo], codes[todo], cond[todo], weight[todo], dofs,
                                               changes)  # fmt: skip
        codes[todo] = new_codes
        decoded = new_decoded if decoded is None else decoded.index_copy(0, todo, new_decoded)  # (B, 22)
        if tolerance_rad > 0:  # rows within the tolerance leave the search
            w = weight[todo]  # (T, J)
            mae = ((new_decoded[:, dofs] - x_active[todo]).abs() * w).sum(-1) / w.sum(-1).clamp_min(1)  # (T,) radians
            todo = todo[mae > tolerance_rad]
            if not len(todo):
                break
    return codes, decoded


def _greedy_round(model, x, codes, cond, weight, dofs, changes: int) -> tuple[torch.Tensor, torch.Tensor]:
    """One round on (B, J) active-DoF states `x`: ((B, N, K) codes, (B, 22) the states they decode to)."""
    vq = model.quantizer
    b, n_tok, n_grp = codes.shape
    size, positions = vq.codebook_size, n_tok * n_grp
    table = code_effects(model)  # (C, K S)
    rows = torch.arange(b, device=x.device)  # (B,)
    j = len(dofs)
    zq = vq.get_output_from_indices(codes)  # (B, N, C)
    decoded, jac = decoded_and_jacobian(model, zq, cond, dofs)  # (B, 22), (B, J, N, C)
    x_hat = decoded[:, dofs]  # (B, J)
    start_err = (((x_hat - x) * weight) ** 2).sum(-1)  # (B,)
    # effect on x_hat of every code at every position: (B, P, S, J), P = N K positions
    effect = (jac.transpose(1, 2) @ table).view(b, n_tok, j, n_grp, size)  # (B, N, J, K, S)
    effect = effect.permute(0, 1, 3, 4, 2).reshape(b, positions, size, j) * weight[:, None, None, :]
    chosen = codes.reshape(b, positions).clone()  # (B, P)
    delta = effect - effect.gather(2, chosen[:, :, None, None].expand(b, positions, 1, j))  # (B, P, S, J)
    delta = delta.view(b, positions * size, j)  # (B, P S, J): one row per single change
    delta_sq = (delta**2).sum(-1, keepdim=True)  # (B, P S, 1)
    residual = ((x - x_hat) * weight)[:, :, None]  # (B, J, 1) what the changes should add
    codes_of_a_position = torch.arange(size, device=x.device)  # (S,)
    for _ in range(changes):
        # change in squared error of each single change: |r - d|^2 - |r|^2 = |d|^2 - 2 d.r
        gain, best = torch.baddbmm(delta_sq, delta, residual, alpha=-2).squeeze(-1).min(1)  # (B,), (B,)
        better = gain < 0  # (B,)
        if not bool(better.any()):
            break
        best = torch.where(better, best, chosen[:, 0])  # (B,) rows without a gain keep position 0's code
        pos, code = best // size, best % size  # (B,), (B,)
        residual = residual - delta[rows, best, :, None]  # (B, J, 1)
        chosen[rows, pos] = code
        span = (pos * size)[:, None] + codes_of_a_position  # (B, S) the changes of `pos`
        moved = effect[rows, pos] - effect[rows, pos, code][:, None, :]  # (B, S, J) relative to the new code
        delta[rows[:, None], span] = moved
        delta_sq[rows[:, None], span] = (moved**2).sum(-1, keepdim=True)
    chosen = chosen.view(b, n_tok, n_grp)
    decoded_new = model._decode_latent(vq.get_output_from_indices(chosen), cond)  # (B, 22)
    new_err = (((decoded_new[:, dofs] - x) * weight) ** 2).sum(-1)  # (B,)
    better = new_err < start_err  # (B,)
    return torch.where(better[:, None, None], chosen, codes), torch.where(better[:, None], decoded_new, decoded)


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
