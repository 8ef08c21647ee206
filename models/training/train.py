"""`nvr train`: fit NVR or NVR+ to a data folder, resumable, on one CPU or many GPUs/machines.

A run folder holds:
    run.json                    the TrainConfig and the network config (what made the run)
    log.csv                     one line per logged step: loss, L1, perceptual, time, MSE
    checkpoint.safetensors      weights + Adam state + step + where the epochs began, written atomically every few minutes
    model.safetensors           the final weights (models/networks/checkpoint.py format), written at the end

Samples are read in epochs, each a permutation fixed by (seed, epoch), so a resumed run sees exactly the
batches it would have seen; a run resumed on other data starts a new first epoch there. DDP ranks split each
global batch: rank r takes items r, r + world, ... (launch with `torchrun --nproc_per_node N -m app.cli train ...`).
"""

from __future__ import annotations

import csv
import functools
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import torch
from safetensors.torch import load_file, save_file
from torch import nn

from models.threads import set_threads
from models.training.config import TrainConfig
from renderer.errors import InputError
from renderer.io import atomic_path, load_json, remove_stale_temporaries, save_json

RUN_FORMAT = 1
# Limits of the training options: beyond them a run cannot be meant (or would not fit in memory).
CHECKPOINT = "checkpoint.safetensors"
FINAL_MODEL = "model.safetensors"
LOG_COLUMNS = ["step", "loss", "l1", "perceptual", "seconds", "mse"]


def learning_rate(config: TrainConfig, step: int) -> float:
    """Adam's step size at `step` (0-based): config.lr, then over the run's last lr_decay_steps steps a linear
    fall to lr * lr_final_fraction, reached on the last step. A late fall takes out the gradient noise that a
    constant rate leaves in the weights; on resume it follows from the step alone."""
    decay = min(config.lr_decay_steps, config.steps)
    start = config.steps - decay
    if decay <= 0 or step < start:
        return config.lr
    progress = (step - start + 1) / decay
    return config.lr * (1.0 - progress * (1.0 - config.lr_final_fraction))


def batch_indices(seed: int, step: int, batch: int, count: int, origin: int = 0) -> torch.Tensor:
    """The global batch of a step: `batch` sample indices in [0, count), fixed by (seed, step). The run reads the
    samples in epochs, each a permutation of all of them fixed by (seed, epoch): every sample once an epoch, where
    drawing with replacement leaves a third of them unseen after as many draws as there are samples. The first
    epoch starts at step `origin`, where the run's data last changed."""
    positions = (step - origin) * batch + torch.arange(batch)
    epochs, offsets = positions // count, positions % count
    return torch.stack([_epoch_order(seed, int(e), count)[int(o)] for e, o in zip(epochs, offsets)])


@functools.lru_cache(maxsize=2)
def _epoch_order(seed: int, epoch: int, count: int) -> torch.Tensor:
    """The order of the samples in one epoch (a batch may straddle two)."""
    return torch.randperm(count, generator=torch.Generator().manual_seed(seed * 1_000_003 + epoch))


@dataclass
class Distributed:
    """Where this process sits in a torch.distributed job (world 1 when not launched by torchrun)."""

    rank: int = 0
    world: int = 1

    @classmethod
    def from_environment(cls, device: str) -> Distributed:
        world = int(os.environ.get("WORLD_SIZE", "1"))
        if world == 1:
            return cls()
        import torch.distributed as dist

        if not dist.is_initialized():
            dist.init_process_group("nccl" if device.startswith("cuda") else "gloo")
        return cls(dist.get_rank(), world)

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def network_config(train: TrainConfig):
    """The network config a run trains (a named configuration, with any overrides)."""
    from models.networks.config import CONFIGS as classes

    if train.config not in classes:
        raise InputError(f"unknown network config {train.config!r} (choose from {', '.join(classes)})")
    from models.networks.checkpoint import network_shapes

    try:
        config = classes[train.config](**dict(train.config_overrides))
    except (TypeError, ValueError) as exc:
        raise InputError(f"network config: {exc}") from None
    try:
        network_shapes(train.architecture, config)
    except InputError as exc:
        raise InputError(f"network config: {exc}") from None  # too large to build
    return config


# --- checkpoints for resuming ---------------------------------------------------------------


@dataclass(frozen=True)
class EpochOrigin:
    """The step where the run's first epoch over its data began, and what that data was (folders and samples)."""

    step: int
    data: str

    @staticmethod
    def describe(folders: tuple[str, ...], samples: int) -> str:
        return json.dumps({"data": list(folders), "samples": samples})


def save_training_state(path: Path, model: nn.Module, optimizer: torch.optim.Optimizer, step: int,
                        epochs: EpochOrigin) -> None:
    """Weights, Adam moments, the step and where the epochs of the run's data began in one safetensors file (no
    pickle), written atomically."""
    tensors = {f"model.{k}": v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    for index, state in optimizer.state_dict()["state"].items():
        for key, value in state.items():
            tensors[f"optim.{index}.{key}"] = torch.as_tensor(value).detach().contiguous().cpu()
    metadata = {"format": str(RUN_FORMAT), "step": str(step), "epoch_origin": str(epochs.step), "epoch_data": epochs.data}
    with atomic_path(path) as tmp:
        save_file(tensors, str(tmp), metadata=metadata)


def load_training_state(path: Path, model: nn.Module, optimizer: torch.optim.Optimizer,
                        data: str) -> tuple[int, EpochOrigin]:
    """Restore weights and Adam state in place; returns the step to continue from and where the epochs over `data`
    (EpochOrigin.describe) began: where the checkpoint says, if it was trained on the same data, else at that step
    (a checkpoint from before epochs were recorded counts as other data)."""
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework="pt") as f:
            metadata = f.metadata() or {}
        tensors = load_file(str(path))
    except Exception as exc:  # safetensors raises several types for a damaged file
        raise InputError(f"not a readable checkpoint ({exc})", path) from None
    if metadata.get("format") != str(RUN_FORMAT):
        raise InputError(f"checkpoint format {metadata.get('format')!r}, expected {RUN_FORMAT}", path)
    weights = {k[len("model."):]: v for k, v in tensors.items() if k.startswith("model.")}
    try:
        model.load_state_dict(weights)
    except RuntimeError as exc:
        raise InputError(f"checkpoint does not fit this network: {str(exc).splitlines()[0]}", path) from None
    state: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in tensors.items():
        if key.startswith("optim."):
            _, index, name = key.split(".", 2)
            state.setdefault(int(index), {})[name] = value
    optimizer_state = optimizer.state_dict()
    optimizer_state["state"] = state
    optimizer.load_state_dict(optimizer_state)
    step = int(metadata["step"])
    if metadata.get("epoch_data") == data and "epoch_origin" in metadata:
        return step, EpochOrigin(int(metadata["epoch_origin"]), data)
    return step, EpochOrigin(step, data)


# --- the loop -------------------------------------------------------------------------------


def _prepare_run(out: Path, train: TrainConfig, resume: bool, net_config) -> dict[str, str]:
    """Write (or, on resume, update) the run's run.json; returns what the run started from (see `_init_record`),
    read when the run began: the --init file may be overwritten by the run's own model before the run ends."""
    record = {"format": RUN_FORMAT, "train": train.to_dict(), "network": net_config.to_dict(),
              "started_from": _init_record(train.init)}
    run_file = out / "run.json"
    if run_file.exists():
        if not resume:
            raise InputError("holds a run already; pass --resume to continue it or choose another --out", out)
        stored = load_json(run_file)
        if stored.get("network") != record["network"] or stored.get("train", {}).get("architecture") != train.architecture:
            raise InputError("holds a run of another network; choose another --out", out)
        if stored.get("train", {}).get("freeze_voxel_branch", False) != train.freeze_voxel_branch:
            raise InputError("holds a run whose voxel branch was " + ("" if train.freeze_voxel_branch else "not ")
                             + "trained; resume it with the same --freeze-voxel-branch choice", out)
        started_from = stored.get("started_from", _init_record(stored.get("train", {}).get("init")))
        save_json(run_file, {**stored, "train": train.to_dict(), "started_from": started_from})  # steps may change
        return started_from
    else:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create the run folder: {exc.strerror}", out) from None
        save_json(run_file, record)
    return record["started_from"]


def train(out: str | Path, config: TrainConfig, resume: bool = False, progress: bool = True) -> Path:
    """Train (or resume) a run; returns the path of the final model file."""
    from tqdm import tqdm

    from models.networks.checkpoint import save_model
    from models.networks.nvr import build_model, reads_floor_light, reads_shading
    from models.training.data import VoxelRenderSet, color_orders, permute_colors
    from models.training.loss import RenderLoss

    out = Path(out)
    dist_info = Distributed.from_environment(config.device)
    if config.threads:
        set_threads(config.threads)
    if config.batch % dist_info.world:
        raise InputError(f"--batch {config.batch} must be divisible by the number of processes {dist_info.world}")
    if config.device.startswith("cuda") and not torch.cuda.is_available():
        raise InputError("--device cuda was asked for, but no CUDA device is available")
    device = torch.device(config.device if dist_info.world == 1 or not config.device.startswith("cuda")
                          else f"cuda:{dist_info.rank % torch.cuda.device_count()}")
    net_config = network_config(config)
    dataset = VoxelRenderSet(list(config.data), grid_size=net_config.grid_size,
                             floor_light=reads_floor_light(config.architecture, net_config),
                             shading=reads_shading(config.architecture, net_config),
                             shading_grid_factor=net_config.shading_grid_factor,
                             environment=net_config.environment_input)
    dataset.check_samples(net_config.output_size)  # a broken or mis-sized sample is refused before step 0
    torch.manual_seed(config.seed)  # identical initial weights on every rank
    model = build_model(config.architecture, net_config)
    if config.init and not resume:
        initialize_from(model, Path(config.init))
    model = model.to(device)
    if config.freeze_voxel_branch:
        model.voxel_encoder.requires_grad_(False)
    if dist_info.world > 1:
        from models.training.distributed import convert_batchnorm

        model = convert_batchnorm(model, device)  # statistics over the global batch, as in one process
    loss_fn = RenderLoss(net_config.perceptual_weight, weights_path=config.perceptual_weights,
                         mse_weight=config.mse_weight).to(device)
    # Only now, with the data, the --init file and the loss's weights read, is the run folder written: a run refused
    # before it starts leaves no folder that the same command, run again, would take for a run to --resume.
    started_from: dict[str, str] = {}
    if dist_info.is_main:
        started_from = _prepare_run(out, config, resume, net_config)
        remove_stale_temporaries(out)  # a checkpoint half-written when a run was killed
    optimizer = torch.optim.Adam([p for p in model.parameters() if p.requires_grad], lr=config.lr)
    start_step, epochs = 0, EpochOrigin(0, EpochOrigin.describe(tuple(config.data), len(dataset)))
    if resume and (out / CHECKPOINT).exists():
        start_step, epochs = load_training_state(out / CHECKPOINT, model, optimizer, epochs.data)
    trained = model
    if dist_info.world > 1:
        trained = nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)

    log_path = out / "log.csv"
    new_log = not log_path.exists() or start_step == 0
    # A resumed run keeps its log's columns (logs from before the squared-error term have no "mse").
    columns = LOG_COLUMNS if new_log else _log_columns(log_path)
    if not new_log and dist_info.is_main:
        _drop_rows_from(log_path, start_step)
    log_file = open(log_path, "w" if new_log else "a", newline="") if dist_info.is_main else None
    writer = csv.DictWriter(log_file, columns, extrasaction="ignore") if log_file else None
    if writer and new_log:
        writer.writeheader()
    half = torch.autocast(device.type, dtype=torch.bfloat16, enabled=config.precision == "bf16")
    bar = tqdm(total=config.steps, initial=start_step, disable=not (progress and dist_info.is_main), unit="step")
    started = last_save = time.monotonic()
    model.train()
    if config.freeze_voxel_branch:
        model.voxel_encoder.eval()  # its BatchNorms keep their statistics
    batches = iter(step_batches(dataset, config, start_step, dist_info, epochs.step))
    for step in range(start_step, config.steps):
        batch = {key: value.to(device) for key, value in next(batches).items()}
        if config.color_permutation:
            batch = permute_colors(batch, color_orders(config.seed, step, config.batch)[dist_info.rank :: dist_info.world])
        splat = batch["splat"] if config.architecture == "nvr_plus" else None
        with half:
            prediction = trained(batch["voxels"], batch["light"], splat, batch.get("floor_light"), batch.get("shading"))
            loss, parts = loss_fn(prediction.float(), batch["target"], crop=crop_box(config, step, prediction.shape[-1]))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        for group in optimizer.param_groups:
            group["lr"] = learning_rate(config, step)
        optimizer.step()
        value = float(loss.detach())
        if not torch.isfinite(loss.detach()):
            raise RuntimeError(f"training diverged at step {step} (loss {value})")
        bar.update(1)
        bar.set_postfix(loss=f"{value:.4f}")
        if writer and (step % config.log_every == 0 or step == config.steps - 1):
            writer.writerow({"step": step, "loss": f"{value:.6f}", "seconds": f"{time.monotonic() - started:.1f}",
                             **{key: f"{part:.6f}" for key, part in parts.items()}})
            log_file.flush()
        if dist_info.is_main and time.monotonic() - last_save > 60 * config.checkpoint_minutes:
            save_training_state(out / CHECKPOINT, model, optimizer, step + 1, epochs)
            last_save = time.monotonic()
    bar.close()
    final = out / FINAL_MODEL
    if dist_info.is_main:
        save_training_state(out / CHECKPOINT, model, optimizer, config.steps, epochs)
        save_model(final, model, net_config, {"architecture": config.architecture, "steps": str(config.steps),
                                               "data": json.dumps(list(config.data)),
                                               "perceptual_weights": loss_fn.weights_name,
                                               **started_from})
        log_file.close()
    return final


def _drop_rows_from(log_path: Path, step: int) -> None:
    """Remove the log's rows of `step` and later: a run killed after its last checkpoint logged steps that the
    resumed run logs again."""
    with open(log_path, newline="") as f:
        lines = f.read().splitlines(keepends=True)
    kept = lines[:1] + [line for line in lines[1:] if _row_step(line) < step]
    if len(kept) < len(lines):
        with atomic_path(log_path) as temporary:
            temporary.write_text("".join(kept))


def _row_step(line: str) -> float:
    """The step of a log row (rows that do not start with one count as before every step)."""
    try:
        return float(line.split(",", 1)[0])
    except ValueError:
        return -1.0


def _log_columns(log_path: Path) -> list[str]:
    """The header of an existing log.csv (the columns a resumed run goes on writing)."""
    with open(log_path, newline="") as f:
        header = next(csv.reader(f), None)
    return header or LOG_COLUMNS


def initialize_from(model: nn.Module, path: Path) -> None:
    """Start from another model's weights: equal shapes are copied; a layer that now reads more input
    channels (e.g. the splat branch with `floor_light_input`) gets the old weights on its first
    channels and zeros on the new ones, so the network starts out computing what the old one did.

    NVR may start from NVR+ (the other way round has nothing to gain): the branches both have,
    voxel encoder and light decoder, come over, and NVR's own output layer keeps its fresh weights.
    An NVR+ that reads the environment (config.environment_input) may start from one that does not: its environment
    encoder keeps its fresh weights, whose last layer is zero, so it starts out rendering what the source renders.
    An NVR+ that corrects the shaded image (config.shading_input) may start from one that does not:
    everything but its correction layer comes over, so it starts out rendering the shaded image.
    A refiner working at another resolution (config.correction_downsampling) may start from one that does not:
    the decoder stages both have come over, the source's extra ones are left out and this network's extra ones keep
    their fresh weights; `to_features`, which then reads a decoder stage of another width, starts at zero, so the
    network starts out correcting from the splat branch alone.
    """
    from models.networks.checkpoint import load_model
    from models.networks.nvr import ENVIRONMENT_ENCODER, SHARED_BRANCHES

    source, _, _ = load_model(path)
    old, new = source.state_dict(), model.state_dict()
    rescaled = (source.architecture == model.architecture == "nvr_plus" and source.config.shading_input
                and model.config.shading_input
                and source.config.correction_downsampling != model.config.correction_downsampling)
    if rescaled:
        keys = [key for key in new if key in old]
        for key in set(new) - set(old):
            if not key.startswith("light_decoder.decoder."):
                raise InputError(f"has no layer {key}; --init needs the same layers", path)
    elif source.architecture == model.architecture:
        if model.config.environment_input and not source.config.environment_input:
            new_keys = {key for key in new if not key.startswith(ENVIRONMENT_ENCODER)}
        else:
            new_keys = set(new)
        if set(old) != new_keys:
            raise InputError("its layers differ from this network's; --init needs the same layers", path)
        keys = sorted(new_keys)
    elif (source.architecture, model.architecture) == ("nvr_plus", "nvr"):
        keys = [key for key in new if key.startswith(SHARED_BRANCHES)]
    else:
        raise InputError(f"holds a {source.architecture} network, not {model.architecture}", path)
    if model.config.shading_input and not source.config.shading_input:
        # A network that corrects the shaded image keeps its correction layer at zero (no correction), so it
        # starts out rendering the shaded image; the rest of the image branch comes over.
        keys = [key for key in keys if not key.startswith("rerender.to_rgb.")]
    for key in keys:
        value, target = old[key], new[key]
        if rescaled and key.startswith("to_features.") and value.shape != target.shape:
            target.zero_()
        elif value.shape == target.shape:
            target.copy_(value)
        elif (value.ndim == target.ndim >= 2 and value.shape[0] == target.shape[0] and value.shape[2:] == target.shape[2:]
              and value.shape[1] < target.shape[1]):
            target.zero_()
            target[:, : value.shape[1]].copy_(value)
        else:
            raise InputError(f"layer {key} has shape {tuple(value.shape)}, this network's {tuple(target.shape)}", path)


def _init_record(init: str | None) -> dict[str, str]:
    """What a model started from, for its metadata: the weights file and how many steps in all stand behind
    it (its own run's, plus those of the weights that run started from, as its metadata records them)."""
    if not init:
        return {}
    from models.networks.checkpoint import load_model

    try:
        extra = load_model(init)[2]
        steps = str(int(extra["steps"]) + int(extra.get("init_steps", 0)))
    except (InputError, KeyError, ValueError):
        steps = "?"  # moved or deleted since the run began: the path alone is still worth keeping
    return {"init": init, "init_steps": steps}


def crop_box(config: TrainConfig, step: int, size: int) -> tuple[int, int, int] | None:
    """(top, left, side) of the step's perceptual crop, the same on every rank; None for the whole image.

    VGG features of a 256^2 image cost about 70% of a compact training step; a 128^2 crop keeps
    the term's gradient (it is local) at a quarter of the cost.
    """
    side = config.perceptual_crop
    if side <= 0 or side >= size:
        return None
    generator = torch.Generator().manual_seed(config.seed * 7_919 + step)
    top, left = (int(v) for v in torch.randint(size - side + 1, (2,), generator=generator))
    return top, left, side


def collate(items: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """Stack samples into a batch."""
    return {key: torch.stack([item[key] for item in items]) for key in items[0]}


class _StepIndices(torch.utils.data.Sampler):
    """Each step's share of its global batch (batch_indices), from `start` on: the same samples whichever
    process prepares them."""

    def __init__(self, config: TrainConfig, start: int, count: int, dist_info: Distributed, origin: int):
        self.config, self.start, self.count, self.dist_info, self.origin = config, start, count, dist_info, origin

    def __iter__(self):
        c, d = self.config, self.dist_info
        for step in range(self.start, c.steps):
            yield batch_indices(c.seed, step, c.batch, self.count, self.origin)[d.rank :: d.world].tolist()

    def __len__(self) -> int:
        return max(self.config.steps - self.start, 0)


def step_batches(dataset, config: TrainConfig, start: int, dist_info: Distributed, origin: int):
    """The batches of steps `start`, start + 1, ... (epochs counted from step `origin`); with config.loader_workers,
    prepared by worker processes while the steps before them run (a sample's grid, shading and images take about a
    third of a step on a 2-core CPU, and most of that is single-threaded numpy). Workers start fresh interpreters (spawn): a fork
    would inherit the compiled kernels' OpenMP threads, which do not survive it."""
    from torch.utils.data import DataLoader

    workers = config.loader_workers
    sampler = _StepIndices(config, start, len(dataset), dist_info, origin)
    return DataLoader(dataset, batch_sampler=sampler, collate_fn=collate,
                      num_workers=workers, multiprocessing_context="spawn" if workers else None,
                      worker_init_fn=_quiet_worker if workers else None, prefetch_factor=2 if workers else None)


def _quiet_worker(_: int) -> None:
    """A loader worker computes on one thread, leaving the cores to the training step."""
    set_threads(1)
