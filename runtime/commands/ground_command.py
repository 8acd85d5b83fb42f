"""`goalvla ground`: read PAIR.npz, ground with the profile's feature backend, write RESULT.json."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from runtime.config import Profile


def ground_command(profile: Profile, pair_file: Path, out: Path) -> int:
    from drivers.files import InputFileError, check_output_path
    from pipeline.grounding.ground import ground
    from pipeline.grounding.pair_io import load_pair
    from pipeline.grounding.types import GroundingError
    from pipeline.perception.features import features_from_config

    try:
        check_output_path(out, "RESULT.json (--out)")
        pair = load_pair(pair_file)
    except (GroundingError, InputFileError) as e:
        typer.secho(f"error: {e}", fg=typer.colors.RED, err=True)
        return 2
    motion = ground(pair, features_from_config(profile.pipeline), profile.pipeline.grounding)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(motion.to_json(), indent=1))
    except OSError as e:
        typer.secho(f"error: {out}: cannot write RESULT.json ({e.strerror or e})", fg=typer.colors.RED, err=True)
        return 2
    if motion.ok:
        typer.echo(
            f"grounded: |t| {1000 * float((motion.t**2).sum() ** 0.5):.1f} mm, {motion.inliers} inliers -> {out}"
        )
        return 0
    typer.secho(f"refused: {motion.reason} -> {out}", fg=typer.colors.YELLOW, err=True)
    return 1
