"""One resolved configuration per run: `resolve_config` merges what the command line or an
API call asks for (`options.Requested`), the input's settings (project.toml, or what the
source program states) and the defaults into one frozen `options.Config`; `configure`
applies its data part to the block as read.  Every command goes through them
(`read_configured`: the input read and configured, its block and its Config), so that no
setting is resolved twice or forgotten.

The rule of every setting (a value given twice: the first column wins, and the run notes
it where project.toml gave another):

| setting | command line / API | the input | default |
|---|---|---|---|
| alpha0, beta0, alpha_global | --alpha0, --beta0, --alpha-global | [tests] | 0.001, 0.8, 0.05 |
| datum | --datum, --free | datum (free: COLMAP, BAL, AICON) | control |
| CRS | --crs | crs | none |
| camera model | --camera-model | cameras.csv `model`, the source program's | none |
| estimated | --calibrate (replaces the input's) | [calibration] free, the source's | none |
| calibration group | --calibration-group | [calibration] group | camera |
| image sigma | --sigma-image-um, --sigma-px, --pixel-mm | the files', image_um | image_sigma.py |
| solver | --damping | | the bundle's (Gauss-Newton) |

With --camera-model and no --calibrate, the parameters the input estimates stay estimated
where the new model has them (c, x0, y0 always); the others are dropped; both are noted.
"""

from __future__ import annotations

from dataclasses import replace

from baarda.block.camera import (
    INPUT_CALIBRATION,
    calibrate_note,
    cameras_per_strip,
    chosen_parameters,
    parameter_names,
    with_camera_model,
)
from baarda.block.photo_block import Block, Settings
from baarda.errors import ProjectError
from baarda.options import (
    CALIBRATION_GROUPS,
    DATUMS,
    SOLVERS,
    CalibrationConfig,
    Config,
    ImageOptions,
    Requested,
    TestOptions,
)

# (the option's name, the Requested field, the Settings field, project.toml's key)
_OVER_PROJECT = (("--alpha0", "alpha0", "alpha0", "tests.alpha0"),
                 ("--beta0", "beta0", "beta0", "tests.beta0"),
                 ("--alpha-global", "alpha_global", "alpha_global", "tests.alpha_global"),
                 ("--datum", "datum", "datum", "datum"),
                 ("--crs", "crs", "crs", "crs"),
                 ("--calibration-group", "calibration_group", "calibration_group",
                  "calibration.group"))


def resolve_tests(settings=None, alpha0: float | None = None, beta0: float | None = None,
                  alpha_global: float | None = None) -> TestOptions:
    """The tests: the values given, else the project's settings, else the defaults; a bad
    value given is a ProjectError of the command line."""
    try:
        return TestOptions.resolve(settings, alpha0, beta0, alpha_global)
    except ValueError as e:
        raise ProjectError("command line", str(e)) from None


def check_requested(r: Requested) -> None:
    """ValueError for a solver, datum or calibration group that is none (the API's words;
    the command line's choices allow only these)."""
    if r.solver not in (None, *SOLVERS):
        raise ValueError(f"unknown solver {r.solver!r}: one of {', '.join(SOLVERS)}")
    if r.datum not in (None, *DATUMS):
        raise ValueError(f"datum '{r.datum}' is not one of {', '.join(DATUMS)}")
    if r.calibration_group not in (None, *CALIBRATION_GROUPS):
        raise ValueError(f"calibration group '{r.calibration_group}' is not one of "
                         f"{', '.join(CALIBRATION_GROUPS)}")


def resolve_config(requested: Requested | None = None, block: Block | None = None,
                   fmt: str | None = None) -> Config:
    """The configuration of a run (module docstring): `requested` over the input's
    settings (`block` as read, None: no input, e.g. a flight plan) over the defaults;
    `fmt`: the input's format (its image options; None: none).  ProjectError for a
    setting that does not apply (naming the command line or project.toml)."""
    r = requested or Requested()
    s = block.settings if block is not None else Settings()
    check_requested(r)
    tests = resolve_tests(s if block is not None else None, r.alpha0, r.beta0, r.alpha_global)
    notes = [f"{option} {getattr(r, field)} (given) over project.toml's {key} = "
             f"{getattr(s, own)!r}" for option, field, own, key in _OVER_PROJECT
             if getattr(r, field) is not None and key in s.given
             and getattr(r, field) != getattr(s, own)]
    group = r.calibration_group or s.calibration_group
    calibration = CalibrationConfig(model=r.camera_model, group=group)
    if block is not None:
        calibration, said = _calibration(r, block, fmt, group)
        notes += said
    image = ImageOptions()
    if fmt is not None:
        from baarda.io.image_sigma import resolve_image_options

        image = resolve_image_options(fmt, r.pixel_mm, r.sigma_px, r.sigma_image_um)
    return Config(tests=tests, solver=r.solver, datum=r.datum or s.datum,
                  crs=r.crs or s.crs, calibration=calibration, image=image,
                  notes=tuple(notes))


def _calibration(r: Requested, block: Block, fmt: str | None,
                 group: str) -> tuple[CalibrationConfig, list[str]]:
    """The calibration of the run and its notes (module docstring's rule)."""
    cams = block.cameras
    stated = block.settings.calibration_free
    source = ("project.toml [calibration] free" if fmt == "project" else
              "as the input estimates them")
    where = (f"{block.source}/project.toml" if fmt == "project" else
             block.source or "input")
    model = r.camera_model
    target = cams
    if model is not None:
        try:
            target = with_camera_model(block, model).cameras
        except ValueError as e:
            raise ProjectError("command line", f"--camera-model: {e}") from None
    if r.calibrate is not None:
        try:
            free = chosen_parameters(target, r.calibrate)
        except ValueError as e:
            raise ProjectError("command line", str(e)) from None
        return (CalibrationConfig(model, free, group, "command line"),
                [calibrate_note(r.calibrate)])
    if stated is None:
        return CalibrationConfig(model, None, group, "none"), []
    names = [parameter_names(target, i) for i in range(len(target))]
    if model is None:  # each camera's own model: every name must be one of its parameters
        for i, f in enumerate(stated):
            bad = [p for p in f if p not in names[i]]
            if bad:
                raise ProjectError(where, f"camera {cams.ids[i]}: '{bad[0]}' is not a "
                                   f"parameter of its model ({', '.join(names[i])})",
                                   column="calibration")
        return CalibrationConfig(None, tuple(stated), group, source), []
    kept = tuple(tuple(p for p in f if p in names[i]) for i, f in enumerate(stated))
    dropped = sorted({p for i, f in enumerate(stated) for p in f if p not in names[i]})
    if not any(stated):
        return CalibrationConfig(model, kept, group, source), []
    union = list(dict.fromkeys(p for f in kept for p in f))
    what = (", ".join(union) if len(set(kept)) == 1 else
            "per camera " + "; ".join(f"{cams.ids[i]}: {', '.join(f) or 'none'}"
                                      for i, f in enumerate(kept)))
    note = (f"--camera-model {model}: {what or 'nothing'} estimated ({source})"
            + (f"; {', '.join(dropped)} dropped (not a parameter of camera model "
               f"{model})" if dropped else ""))
    return CalibrationConfig(model, kept, group, source), [note]


def configure(block: Block, config: Config) -> Block:
    """The block as the configuration has it: its CRS and datum in the settings, every
    camera on the configuration's model with its free parameters, the configuration's
    notes, and the cameras split per strip for the calibration group "strip"."""
    s = block.settings
    if config.crs != s.crs or config.datum != s.datum:
        block = replace(block, settings=replace(s, crs=config.crs, datum=config.datum))
    cal = config.calibration
    if cal.model is not None:
        block = with_camera_model(block, cal.model)
    if cal.free is not None:
        block = replace(block, settings=replace(block.settings, calibration_free=cal.free))
    notes = block.notes
    if cal.source == "command line":  # the input's own calibration note no longer holds
        notes = [n for n in notes if not n.startswith(INPUT_CALIBRATION)]
    if config.notes or notes != block.notes:
        block = replace(block, notes=[*notes, *config.notes])
    block = replace(block, settings=replace(block.settings, calibration_group=cal.group))
    return cameras_per_strip(block) if cal.group == "strip" else block
