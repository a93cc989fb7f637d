"""Render a softcontact output directory to PNG frames (and an animation) with ParaView.

Run through the wrapper, which finds ParaView and an off-screen display:

    bash tools/render.sh OUTPUT_DIR [options]

or directly with `pvpython tools/render.py OUTPUT_DIR [options]` where pvpython can open
a window (or `xvfb-run -a pvpython ...`).

It opens OUTPUT_DIR/frames.xdmf, draws the outer surface of every object with smooth
shading, coloured by one field, from a camera fitted once to the whole run, and writes
OUT/frame_NNNNNN.png (NNNNNN: the frame number, as in frames.h5). Object names, the
kinematic (fixed) objects and the colour ranges come from OUTPUT_DIR/frames.h5 (h5py).
Kinematic objects are drawn grey; walls, containers and lids semi-transparent.
See docs/output-format.md, "Pictures and animations".
"""
import argparse
import fnmatch
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time as wallclock

EXIT_BAD_INPUT = 2

# Colour options: XDMF attribute, HDF5 dataset in each frame group, how it is drawn.
FIELDS = {
    "object": {"xdmf": None, "kind": "categorical"},
    "material": {"xdmf": None, "kind": "categorical"},
    "owner_rank": {"xdmf": "owner_rank", "h5": "owner_rank", "kind": "categorical"},
    "velocity": {"xdmf": "velocity", "h5": "velocities", "kind": "magnitude", "unit": "m/s",
                 "title": "|velocity| [m/s]"},
    "contact_force": {"xdmf": "contact_force", "h5": "contact_forces", "kind": "log",
                      "title": "|contact force| [N]"},
    "penetration": {"xdmf": "penetration", "h5": "penetration", "kind": "magnitude",
                    "title": "|penetration| [m]"},
}

# Camera directions (from the focal point towards the camera) and view-up vectors; z is up.
VIEWS = {
    "iso": ((1.0, -1.35, 0.95), (0, 0, 1)),
    "front": ((0, -1, 0.0), (0, 0, 1)),
    "back": ((0, 1, 0.0), (0, 0, 1)),
    "side": ((1, 0, 0.0), (0, 0, 1)),
    "top": ((0, 0, 1), (0, 1, 0)),
    "low": ((1.0, -1.35, 0.35), (0, 0, 1)),
}

# Object colours: bright, distinct, no greys (grey is for kinematic objects).
PALETTE = [
    (0.122, 0.467, 0.706), (1.000, 0.498, 0.055), (0.173, 0.627, 0.173), (0.839, 0.153, 0.157),
    (0.580, 0.404, 0.741), (0.549, 0.337, 0.294), (0.890, 0.467, 0.761), (0.737, 0.741, 0.133),
    (0.090, 0.745, 0.812), (0.400, 0.761, 0.647), (0.988, 0.553, 0.384), (0.553, 0.627, 0.796),
    (0.906, 0.541, 0.765), (0.651, 0.847, 0.329), (1.000, 0.851, 0.184), (0.898, 0.769, 0.580),
]
KINEMATIC_GREY = (0.72, 0.72, 0.74)
NO_CONTACT = (0.74, 0.75, 0.78)
HEAT = [(1.0, 0.93, 0.55), (0.99, 0.62, 0.20), (0.87, 0.20, 0.12), (0.45, 0.0, 0.15)]
GHOST_GREY = (0.80, 0.82, 0.86)

ROLE_COLOURED, ROLE_SOLID_GREY, ROLE_GHOST, ROLE_HIDDEN = 0, 1, 2, 3


def fail(msg, code=EXIT_BAD_INPUT):
    print(f"render: {msg}", file=sys.stderr)
    sys.exit(code)


def parse_args(argv):
    ap = argparse.ArgumentParser(
        prog="tools/render.sh", description="Render a softcontact output directory with ParaView.")
    ap.add_argument("output_dir", help="a run's output directory (with frames.xdmf and frames.h5)")
    ap.add_argument("--frames", default=None,
                    help="all | last | first | a comma list of frame numbers and ranges A:B[:STEP] "
                         "(negative numbers count from the end); default: last, or all with --animation")
    ap.add_argument("--color", "--colour", dest="color", default="object", choices=sorted(FIELDS),
                    help="what colours the surfaces (default: object)")
    ap.add_argument("--out", default=None, help="directory for the PNGs (default: OUTPUT_DIR/pictures)")
    ap.add_argument("--size", default="1280x720", help="image size WxH in pixels (default 1280x720)")
    ap.add_argument("--view", default="iso", choices=sorted(VIEWS), help="camera direction (default iso)")
    ap.add_argument("--zoom", type=float, default=1.0, help="> 1 moves the camera closer (default 1)")
    ap.add_argument("--fit", default="run", choices=["run", "frames"],
                    help="fit the camera to the objects over the whole run (default; the camera stays put "
                         "in an animation) or over the rendered frames only (tighter stills)")
    ap.add_argument("--focus", default=None,
                    help="fit the camera to these objects only (name pattern, e.g. 'bar*'); default: all shown")
    ap.add_argument("--hide", action="append", default=[], metavar="PATTERN",
                    help="do not draw objects whose name matches (fnmatch, e.g. 'wall*'); repeatable")
    ap.add_argument("--ghost", action="append", default=[], metavar="PATTERN",
                    help="draw matching objects grey and semi-transparent; repeatable")
    ap.add_argument("--solid", action="append", default=[], metavar="PATTERN",
                    help="draw matching objects grey and opaque (a kinematic wall that would be ghosted, "
                         "a membrane held at its rim); repeatable")
    ap.add_argument("--edges", action="store_true", help="draw the surface triangle edges of moving objects")
    ap.add_argument("--range", default=None, metavar="MIN:MAX",
                    help="colour range for velocity, contact_force, penetration (default: from the run)")
    ap.add_argument("--animation", action="store_true",
                    help="also assemble the frames into OUT/NAME.mp4 (H.264), or NAME.gif without libx264")
    ap.add_argument("--fps", type=float, default=None,
                    help="animation frame rate (default: about 6 s long, 5 to 30 frames per second)")
    ap.add_argument("--name", default=None, help="animation file name without extension (default: the run's name)")
    ap.add_argument("--title", default=None, help="text in the lower left corner (default: the run's name)")
    ap.add_argument("--quiet", action="store_true", help="print only the summary")
    a = ap.parse_args(argv)
    try:
        w, h = (int(s) for s in a.size.lower().split("x"))
        if w < 16 or h < 16 or w > 8192 or h > 8192:
            raise ValueError
        a.size = (w, h)
    except ValueError:
        fail(f"--size expects WxH with 16 <= W, H <= 8192, got '{a.size}'")
    if not a.zoom > 0:
        fail(f"--zoom expects a positive number, got {a.zoom}")
    if a.fps is not None and not a.fps > 0:
        fail(f"--fps expects a positive number, got {a.fps}")
    if a.range is not None:
        try:
            lo, hi = (float(s) for s in a.range.split(":"))
            if not hi > lo:
                raise ValueError
            a.range = (lo, hi)
        except ValueError:
            fail(f"--range expects MIN:MAX with MIN < MAX, got '{a.range}'")
    return a


def select_frames(spec, n):
    """Frame numbers (0..n-1) named by --frames, in the order given, without repeats."""
    if spec in (None, "last"):
        return [n - 1]
    if spec == "first":
        return [0]
    if spec == "all":
        return list(range(n))
    out = []
    for item in spec.split(","):
        item = item.strip()
        try:
            if ":" in item:
                parts = [int(p) if p.strip() else None for p in item.split(":")]
                if len(parts) > 3:
                    raise ValueError
                if len(parts) == 2 and parts[1] is not None:
                    parts[1] += 1 if parts[1] >= 0 else 0  # A:B includes B
                picked = list(range(n))[slice(*parts)]
            else:
                k = int(item)
                if not -n <= k < n:
                    fail(f"--frames: frame {k} does not exist; the run has frames 0 to {n - 1}")
                picked = [k % n]
        except ValueError:
            fail(f"--frames expects all, last, first or numbers and ranges A:B[:STEP], got '{spec}'")
        out += [k for k in picked if k not in out]
    if not out:
        fail(f"--frames '{spec}' selects no frame; the run has frames 0 to {n - 1}")
    return out


class RunInfo:
    """What frames.h5 says about the run: object names, materials, kinematic objects,
    per-object bounds over the run and the range of the colour field."""

    def __init__(self, h5_path, color, nframes, fit_frames=None, sample_frames=24):
        self.names, self.materials, self.kinematic = [], [], []
        self.object_bounds = None  # (objects, 6): xmin xmax ymin ymax zmin zmax over the sampled frames
        self.field_max, self.num_ranks = None, 1
        try:
            import h5py
            import numpy as np
        except ImportError:
            print("render: h5py is missing (Debian: apt-get install python3-h5py); drawing every object "
                  "coloured and fitting the camera from the XDMF", file=sys.stderr)
            self.ok = False
            return
        self.ok = True
        with h5py.File(h5_path, "r") as f:
            mesh = f["/mesh"]
            nobj = int(mesh.attrs.get("num_objects", 0))
            lines = mesh.attrs.get("objects", b"")
            if isinstance(lines, bytes):
                lines = lines.decode()
            for line in str(lines).splitlines():
                name, _, material = line.partition("\t")
                self.names.append(name)
                self.materials.append(material)
            vobj = mesh["vertex_object"][...]
            nobj = max(nobj, int(vobj.max()) + 1 if len(vobj) else 0)
            while len(self.names) < nobj:
                self.names.append(f"object {len(self.names)}")
                self.materials.append("")
            mass = mesh["vertex_mass"][...] if "vertex_mass" in mesh else np.ones(len(vobj))
            self.kinematic = [bool(np.all(np.isinf(mass[vobj == o]))) if np.any(vobj == o) else False
                              for o in range(nobj)]
            # the frames the XDMF names: a run still going may have started the next one
            groups = sorted(f["/frames"].keys())[:nframes]
            if not groups:
                return
            def thin(gs):  # at most about sample_frames of them, the last one included
                step = max(1, math.ceil(len(gs) / sample_frames))
                return gs[::step] + ([gs[-1]] if (len(gs) - 1) % step else [])

            field_sample = thin(groups)
            bounds_sample = thin([groups[k] for k in fit_frames]) if fit_frames else field_sample
            # objects are contiguous vertex ranges (docs/output-format.md)
            starts = np.searchsorted(vobj, np.arange(nobj + 1))
            contiguous = bool(np.all(np.diff(vobj) >= 0))
            bounds = np.empty((nobj, 6))
            bounds[:, 0::2], bounds[:, 1::2] = np.inf, -np.inf
            fmax, ranks = 0.0, 0
            ds = FIELDS[color].get("h5")
            for g in sorted(set(field_sample) | set(bounds_sample)):
                if g not in bounds_sample:
                    pass
                elif contiguous:
                    x = f["/frames"][g]["positions"][...]
                    nonempty = np.flatnonzero(starts[1:] > starts[:-1])
                    if len(nonempty):
                        at = starts[nonempty]
                        bounds[nonempty, 0::2] = np.minimum(bounds[nonempty, 0::2], np.minimum.reduceat(x, at))
                        bounds[nonempty, 1::2] = np.maximum(bounds[nonempty, 1::2], np.maximum.reduceat(x, at))
                else:
                    x = f["/frames"][g]["positions"][...]
                    for o in range(nobj):
                        xo = x[vobj == o]
                        if len(xo):
                            bounds[o, 0::2] = np.minimum(bounds[o, 0::2], xo.min(axis=0))
                            bounds[o, 1::2] = np.maximum(bounds[o, 1::2], xo.max(axis=0))
                if g in field_sample and ds and ds in f["/frames"][g]:
                    v = f["/frames"][g][ds][...]
                    if color == "owner_rank":
                        ranks = max(ranks, int(v.max()) + 1)
                        continue
                    m = np.linalg.norm(v, axis=1) if v.ndim == 2 else np.abs(v)
                    m = m[~np.asarray(self.kinematic)[vobj]] if any(self.kinematic) else m
                    pos = m[m > 0]
                    if len(pos):
                        # a high percentile, not the maximum: one spike must not wash out the rest
                        fmax = max(fmax, float(np.percentile(pos, 99.5)))
            self.object_bounds = bounds
            self.field_max = fmax
            self.num_ranks = max(ranks, 1)


def assign_roles(info, args):
    """Per object: coloured, grey solid (floors, anchors), ghost (walls, containers) or hidden."""
    import numpy as np

    n = len(info.names)
    roles = [ROLE_COLOURED] * n
    match = lambda o, pats: any(fnmatch.fnmatchcase(info.names[o], p) for p in pats)
    b = info.object_bounds
    moving = [o for o in range(n) if not info.kinematic[o]]
    if b is not None and n:
        centres = [(b[o, 0::2] + b[o, 1::2]) / 2 for o in moving]
    for o in range(n):
        if info.kinematic[o]:
            roles[o] = ROLE_SOLID_GREY
            if b is not None:
                lo, hi = b[o, 0::2], b[o, 1::2]
                ext = hi - lo
                encloses = sum(bool(np.all(c > lo) and np.all(c < hi)) for c in centres) >= max(1, len(moving) // 4)
                # a wall: a standing slab, thin in x or y, at least three times as high as thick
                wall = min(ext[0], ext[1]) < 0.25 * max(ext[0], ext[1]) and ext[2] > 3 * min(ext[0], ext[1])
                # a lid or top anchor: above moving objects, over them
                above = any(c[2] < lo[2] and np.all(c[:2] > lo[:2]) and np.all(c[:2] < hi[:2]) for c in centres)
                # a container around the moving objects, or a wall or lid that would hide them
                if encloses or wall or above:
                    roles[o] = ROLE_GHOST
        if match(o, args.solid):
            roles[o] = ROLE_SOLID_GREY
        if match(o, args.ghost):
            roles[o] = ROLE_GHOST
        if match(o, args.hide):
            roles[o] = ROLE_HIDDEN
    for pats, opt in ((args.hide, "--hide"), (args.ghost, "--ghost"), (args.solid, "--solid")):
        for p in pats:
            if not any(fnmatch.fnmatchcase(nm, p) for nm in info.names):
                print(f"render: warning: {opt} '{p}' matches no object (objects: {summarize_names(info.names)})",
                      file=sys.stderr)
    return roles


def summarize_names(names):
    stems = []
    for nm in names:
        s = nm.split("[")[0]
        if s not in stems:
            stems.append(s)
    return ", ".join(stems[:12]) + (" ..." if len(stems) > 12 else "")


def scene_bounds(info, roles, focus):
    """Bounds of the drawn objects over the whole run, so the camera does not move between
    frames. Objects that fall below the lowest kinematic object (off the edge of a floor)
    do not stretch the bounds downwards."""
    import numpy as np

    b = info.object_bounds
    if b is None:
        return None
    n = len(roles)
    chosen = [o for o in range(n) if roles[o] != ROLE_HIDDEN]
    if focus:
        chosen = [o for o in chosen if fnmatch.fnmatchcase(info.names[o], focus)]
        if not chosen:
            fail(f"--focus '{focus}' matches no drawn object (objects: {summarize_names(info.names)})")
    chosen = [o for o in chosen if np.all(np.isfinite(b[o]))]
    if not chosen:
        return None
    lo = b[chosen][:, 0::2].min(axis=0)
    hi = b[chosen][:, 1::2].max(axis=0)
    kin = [o for o in range(n) if info.kinematic[o] and roles[o] != ROLE_HIDDEN and np.all(np.isfinite(b[o]))]
    if kin and not focus:
        floor = min(b[o, 4] for o in kin)
        lo[2] = max(lo[2], floor - 0.05 * (hi[2] - floor))
    return [lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]]


def fit_camera(view, bounds, direction, up, zoom, size, view_angle=30.0):
    """Camera on `direction` from the centre of `bounds`, at the distance where all eight
    corners of the box fit the image (both the vertical and the horizontal field)."""
    import numpy as np

    lo = np.array(bounds[0::2], dtype=float)
    hi = np.array(bounds[1::2], dtype=float)
    ext = np.maximum(hi - lo, 1e-9 * max(1.0, float(np.max(np.abs(hi)))))
    lo, hi = (lo + hi) / 2 - ext / 2, (lo + hi) / 2 + ext / 2
    c = (lo + hi) / 2
    d = np.array(direction, dtype=float)
    d /= np.linalg.norm(d)
    u = np.array(up, dtype=float)
    u -= d * (u @ d)
    u /= np.linalg.norm(u)
    r = np.cross(u, d)  # image right (camera looks along -d)
    tv = math.tan(math.radians(view_angle) / 2)
    th = tv * size[0] / size[1]
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - c
    # centre the projected box: shift the focal point within the image plane
    px, py = corners @ r, corners @ u
    shift = r * (px.max() + px.min()) / 2 + u * (py.max() + py.min()) / 2
    corners -= shift
    c = c + shift
    px, py, pz = corners @ r, corners @ u, corners @ d
    dist = max(float(np.max(pz + np.abs(px) / th)), float(np.max(pz + np.abs(py) / tv)))
    dist = dist * 1.04 / zoom
    view.CameraFocalPoint = list(c)
    view.CameraPosition = list(c + d * dist)
    view.CameraViewUp = list(u)
    view.CameraViewAngle = view_angle
    view.CameraParallelProjection = 0


ROLE_SCRIPT = """
import numpy as np
from vtkmodules.numpy_interface import dataset_adapter as dsa
inp = self.GetInputDataObject(0, 0)
out = self.GetOutputDataObject(0)
out.ShallowCopy(inp)
w = dsa.WrapDataObject(inp)
ids = np.asarray(w.CellData['tet_object']).astype(np.int64)
table = np.array(%(roles)r, dtype=np.int32)
role = table[np.clip(ids, 0, len(table) - 1)] if len(table) else np.zeros(len(ids), np.int32)
out.GetCellData().AddArray(dsa.numpyTovtkDataArray(np.ascontiguousarray(role), 'render_role'))
cat = np.array(%(category)r, dtype=np.int32)
if len(cat):
    out.GetCellData().AddArray(dsa.numpyTovtkDataArray(
        np.ascontiguousarray(cat[np.clip(ids, 0, len(cat) - 1)]), 'render_category'))
field = %(field)r
if field:
    v = np.asarray(w.PointData[field])
    m = np.linalg.norm(v, axis=1) if v.ndim == 2 else np.abs(v).astype(float)
    floor = %(floor)r
    if floor > 0:
        m = np.where(m > 0, m, floor)  # below the log range: drawn in the "no contact" colour
    out.GetPointData().AddArray(dsa.numpyTovtkDataArray(np.ascontiguousarray(m), 'render_magnitude'))
"""


def main(argv):
    args = parse_args(argv)
    run = os.path.abspath(args.output_dir)
    if not os.path.isdir(run):
        fail(f"output directory '{args.output_dir}' does not exist (run a scene first: "
             f"softcontact run SCENE.yaml --output {args.output_dir})")
    xdmf = os.path.join(run, "frames.xdmf")
    h5 = os.path.join(run, "frames.h5")
    for p in (xdmf, h5):
        if not os.path.isfile(p):
            fail(f"'{p}' is missing: '{args.output_dir}' is not a softcontact output directory, "
                 "or its run wrote no frame yet")
    run_name = os.path.basename(run.rstrip("/"))
    out_dir = os.path.abspath(args.out or os.path.join(run, "pictures"))
    os.makedirs(out_dir, exist_ok=True)
    t_start = wallclock.time()

    try:
        from paraview import simple as pv
    except ImportError as e:
        fail(f"cannot import ParaView's Python module ({e}); run this script with pvpython "
             "(Debian: apt-get install paraview python3-paraview xvfb)")

    field = FIELDS[args.color]
    reader = pv.Xdmf3ReaderS(registrationName="frames", FileName=[xdmf])
    reader.UpdatePipelineInformation()
    tv = reader.TimestepValues
    try:
        times = [float(t) for t in tv]
    except TypeError:
        times = [float(tv)]
    if not times:
        times = [0.0]
    nframes = len(times)
    point_arrays = list(reader.GetProperty("PointArrayInfo")[::2]) if reader.GetProperty("PointArrayInfo") else []
    if field["xdmf"] and field["xdmf"] not in point_arrays:
        fail(f"--color {args.color}: this run has no '{field['xdmf']}' field (it has: "
             f"{', '.join(point_arrays + ['object', 'material'])})")
    reader.PointArrays = [field["xdmf"]] if field["xdmf"] else []
    reader.CellArrays = ["tet_object"]

    frames = select_frames(args.frames if args.frames is not None else ("all" if args.animation else "last"),
                           nframes)
    try:
        info = RunInfo(h5, args.color, nframes, frames if args.fit == "frames" else None)
    except (OSError, KeyError) as e:
        fail(f"cannot read '{h5}': {e}")

    # Roles, colour categories, bounds
    nobj = len(info.names)
    if info.ok:
        roles = assign_roles(info, args)
        bounds = scene_bounds(info, roles, args.focus)
    else:
        roles, bounds = [], None
    if args.color == "material":
        mats = []
        for m in info.materials:
            if m not in mats:
                mats.append(m)
        category = [mats.index(m) for m in info.materials]
        labels = mats
    else:
        category = list(range(nobj))
        labels = info.names

    surface = pv.ExtractSurface(registrationName="surface", Input=reader)
    normals = pv.GenerateSurfaceNormals(registrationName="normals", Input=surface)
    normals.FeatureAngle = 50.0
    normals.Splitting = 1
    magnitude_floor = 0.0
    lo_hi = None
    if field["kind"] in ("magnitude", "log"):
        fmax = info.field_max or 0.0
        if args.range:
            lo_hi = args.range
        elif field["kind"] == "log":
            hi = fmax if fmax > 0 else 1.0
            lo_hi = (hi * 1e-3, hi)
        else:
            lo_hi = (0.0, fmax if fmax > 0 else 1.0)
        if field["kind"] == "log":
            if lo_hi[0] <= 0:
                fail(f"--range for contact_force is drawn on a log scale: MIN must be positive, got {lo_hi[0]}")
            magnitude_floor = lo_hi[0] / 2
    prog = pv.ProgrammableFilter(registrationName="roles", Input=normals)
    prog.OutputDataSetType = "Same as Input"
    prog.Script = ROLE_SCRIPT % {"roles": roles, "category": category,
                                 "field": field["xdmf"] if field["kind"] in ("magnitude", "log") else None,
                                 "floor": magnitude_floor}

    view = pv.CreateView("RenderView")
    view.ViewSize = list(args.size)
    view.OrientationAxesVisibility = 0
    for prop, value in (("UseColorPaletteForBackground", 0), ("BackgroundColorMode", "Gradient"),
                        ("UseFXAA", 1)):
        try:
            setattr(view, prop, value)
        except Exception:  # a property this ParaView version does not have
            pass
    view.Background = [0.93, 0.94, 0.96]   # gradient: Background at the bottom, Background2 at the top
    view.Background2 = [0.58, 0.65, 0.76]
    try:
        view.OrientationAxesVisibility = 0
        view.EnableRenderOnInteraction = 0
    except AttributeError:
        pass

    def threshold(role):
        th = pv.Threshold(registrationName=f"role{role}", Input=prog)
        th.Scalars = ["CELLS", "render_role"]
        th.LowerThreshold = role
        th.UpperThreshold = role
        try:
            th.ThresholdMethod = "Between"
        except AttributeError:
            pass
        return th

    def configure_magnitude_lut(lut):
        try:  # one range for every frame (and every display)
            lut.AutomaticRescaleRangeMode = "Never"
        except AttributeError:
            pass
        if field["kind"] == "log":
            # pale yellow to dark red, evenly in log |F| from lo to hi; below lo (no
            # contact: the zeros are set to lo / 2) the grey of the objects
            lo, hi = lo_hi
            pts = [magnitude_floor] + list(NO_CONTACT) + [lo / 1.25] + list(NO_CONTACT)
            for k, c in enumerate(HEAT):
                pts += [lo * (hi / lo) ** (k / (len(HEAT) - 1))] + list(c)
            lut.UseLogScale = 1
            lut.ColorSpace = "Lab"
            lut.RGBPoints = pts
            lut.RescaleTransferFunction(magnitude_floor, hi)
        else:
            lut.ApplyPreset("Viridis (matplotlib)", True)
            lut.RescaleTransferFunction(lo_hi[0], lo_hi[1])

    present = set(roles) if roles else {ROLE_COLOURED}
    lut_name = None
    if ROLE_COLOURED in present:
        src = threshold(ROLE_COLOURED) if roles else prog
        d = pv.Show(src, view)
        d.SetRepresentationType("Surface With Edges" if args.edges else "Surface")
        if args.edges:
            d.EdgeColor = [0.15, 0.15, 0.18]
        d.Specular = 0.25
        d.SpecularPower = 40.0
        d.Interpolation = "Gouraud"
        if field["kind"] == "categorical":
            arr = ("CELLS", "render_category") if args.color in ("object", "material") else ("POINTS", "owner_rank")
            pv.ColorBy(d, arr)
            lut_name = arr[1]
            lut = pv.GetColorTransferFunction(arr[1])
            lut.InterpretValuesAsCategories = 1
            if args.color == "owner_rank":
                cats = list(range(info.num_ranks))
                names = [f"rank {r}" for r in cats]
            else:
                cats = sorted(set(category))
                names = [labels[c] if c < len(labels) else str(c) for c in cats]
            ann, cols = [], []
            for k, (c, nm) in enumerate(zip(cats, names)):
                ann += [str(c), nm]
                cols += list(PALETTE[c % len(PALETTE)])
            lut.Annotations = ann
            lut.IndexedColors = cols
            show_legend = args.color != "object" and len(cats) <= 16
        else:
            pv.ColorBy(d, ("POINTS", "render_magnitude"))
            lut_name = "render_magnitude"
            lut = pv.GetColorTransferFunction("render_magnitude")
            configure_magnitude_lut(lut)
            show_legend = True
        if show_legend:
            d.SetScalarBarVisibility(view, True)
            bar = pv.GetScalarBar(lut, view)
            bar.Title = field.get("title", args.color.replace("_", " "))
            bar.ComponentTitle = ""
            bar.TitleColor = bar.LabelColor = [0.1, 0.1, 0.12]
            bar.TitleFontSize = max(10, args.size[1] // 50)
            bar.LabelFontSize = max(9, args.size[1] // 60)
            bar.WindowLocation = "Any Location"
            bar.Orientation = "Vertical"
            bar.Position = [0.90, 0.10]
            bar.ScalarBarLength = 0.5
            if field["kind"] == "log":
                bar.UseCustomLabels = 0
                bar.AddRangeLabels = 1
                bar.RangeLabelFormat = "%-#.2g"
        else:
            d.SetScalarBarVisibility(view, False)
    if ROLE_SOLID_GREY in present:
        d = pv.Show(threshold(ROLE_SOLID_GREY), view)
        d.AmbientColor = d.DiffuseColor = list(KINEMATIC_GREY)
        if args.color in ("contact_force", "penetration") and lut_name:
            # the reactions on floors and walls show where the objects press on them
            pv.ColorBy(d, ("POINTS", lut_name))
            configure_magnitude_lut(lut)  # ColorBy rescaled it to this display's data
        else:
            pv.ColorBy(d, None)
        d.Specular = 0.1
    if ROLE_GHOST in present:
        d = pv.Show(threshold(ROLE_GHOST), view)
        pv.ColorBy(d, None)
        d.AmbientColor = d.DiffuseColor = list(GHOST_GREY)
        d.Opacity = 0.22
        # only the faces towards the camera: one transparent layer, and no z-fighting where
        # a lid's underside touches the objects it presses on
        d.BackfaceRepresentation = "Cull Backface"
        try:
            view.EnableRenderOnInteraction = 0
            view.UseDepthPeeling = 1
        except AttributeError:
            pass

    fs = max(10, args.size[1] // 36)
    time_text = pv.Text(registrationName="time")
    td = pv.Show(time_text, view)
    td.WindowLocation = "Upper Left Corner"
    td.FontSize = fs
    td.Color = [0.08, 0.08, 0.1]
    title = pv.Text(registrationName="title")
    title.Text = args.title if args.title is not None else f"{run_name}   colour: {args.color.replace('_', ' ')}"
    tt = pv.Show(title, view)
    tt.WindowLocation = "Lower Left Corner"
    tt.FontSize = max(8, fs * 2 // 3)
    tt.Color = [0.15, 0.15, 0.2]

    direction, up = VIEWS[args.view]
    if bounds is None:
        # no h5py: bounds of the data at a few times
        bb = [math.inf, -math.inf] * 3
        for t in sorted(set([times[0], times[len(times) // 2], times[-1]])):
            reader.UpdatePipeline(t)
            b = reader.GetDataInformation().GetBounds()
            for i in range(3):
                bb[2 * i] = min(bb[2 * i], b[2 * i])
                bb[2 * i + 1] = max(bb[2 * i + 1], b[2 * i + 1])
        bounds = bb
    fit_camera(view, bounds, direction, up, args.zoom, args.size)

    written = []
    for k in frames:
        t = times[k]
        time_text.Text = f"t = {t:.3f} s"
        view.ViewTime = t
        path = os.path.join(out_dir, f"frame_{k:06d}.png")
        pv.SaveScreenshot(path, view, ImageResolution=list(args.size), TransparentBackground=0)
        written.append(path)
        if not args.quiet:
            print(f"render: {path}  (frame {k}, t = {t:.4g} s)", flush=True)
    t_frames = wallclock.time() - t_start
    print(f"render: {len(written)} frame(s) of {nframes} in {out_dir} ({t_frames:.1f} s)")

    if args.animation:
        make_animation(written, out_dir, args.name or run_name, args.fps)
    return 0


def make_animation(pngs, out_dir, name, fps):
    ffmpeg = shutil.which("ffmpeg")
    if not ffmpeg:
        fail("--animation needs ffmpeg (Debian: apt-get install ffmpeg); the PNGs are written")
    if len(pngs) < 2:
        fail("--animation needs at least two frames; the PNG is written")
    if fps is None:
        fps = min(30.0, max(5.0, len(pngs) / 6.0))
    encoders = subprocess.run([ffmpeg, "-hide_banner", "-encoders"], capture_output=True, text=True).stdout
    with tempfile.TemporaryDirectory(prefix="render_") as tmp:
        for i, p in enumerate(pngs):
            os.symlink(p, os.path.join(tmp, f"seq_{i:06d}.png"))
        src = ["-framerate", f"{fps:g}", "-i", os.path.join(tmp, "seq_%06d.png")]
        if "libx264" in encoders:
            target = os.path.join(out_dir, f"{name}.mp4")
            cmd = [ffmpeg, "-y", "-loglevel", "error", *src, "-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2",
                   "-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "23", "-preset", "slow",
                   "-movflags", "+faststart", target]
        else:
            target = os.path.join(out_dir, f"{name}.gif")
            cmd = [ffmpeg, "-y", "-loglevel", "error", *src, "-vf",
                   "scale='min(800,iw)':-1:flags=lanczos,split[a][b];[a]palettegen=max_colors=128[p];[b][p]paletteuse",
                   target]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            fail(f"ffmpeg failed ({' '.join(cmd)}):\n{r.stderr}", code=1)
    size = os.path.getsize(target)
    print(f"render: animation {target} ({len(pngs)} frames at {fps:g}/s, {len(pngs) / fps:.1f} s, "
          f"{size / 1e6:.2f} MB)")


if __name__ == "__main__":
    # ParaView's programmable filter runs its script in the namespace of __main__, which
    # then holds numpy-style max, min, ... instead of the builtins: run from a module of
    # its own instead of from __main__.
    import importlib.util

    spec = importlib.util.spec_from_file_location("softcontact_render", os.path.abspath(__file__))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    code = module.main(sys.argv[1:])
    # ParaView's teardown of the X/GLX context can fail after everything is written
    # ("GLXBadContext") and turn a finished run into exit status 1: leave without it.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
