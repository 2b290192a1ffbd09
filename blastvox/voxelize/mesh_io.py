"""Reading input meshes into solid parts.

Surface formats (OBJ, STL, PLY, OFF, glTF/GLB, ...) go through trimesh; scene
graphs are flattened with their node transforms, one part per node. Volume
formats that meshio reads (.vtu, .vtk, .msh, ... with tetrahedra or hexahedra)
become their boundary surface. A part keeps its base colour texture and UVs, or,
coloured per vertex or per face, a texture baked from its colours
(:mod:`blastvox.voxelize.vertex_colors`). Every failure is a :class:`MeshError`
naming the file and the problem.
"""

from __future__ import annotations

import base64
import contextlib
import io
import json
import os
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from blastvox.bounds import printable, regular_file, shortened
from blastvox.errors import InputError, MeshError
from blastvox.geometry.voxel_faces import VTK_CELL_FACES
from blastvox.io import mesh_checks
from blastvox.io.references import ReferencePolicy, ReferenceRefused, read_uri
from blastvox.voxelize import vertex_colors

#: Suffixes read through meshio as volume meshes rather than through trimesh.
VOLUME_SUFFIXES = {".vtu", ".vtk", ".msh", ".mesh", ".xdmf", ".med", ".inp", ".vol"}


@dataclass
class Part:
    """One surface of an input file, in the file's coordinates (metres).

    mesh: the triangle surface after the node transform.
    name: node or geometry name, for messages and object names.
    material: the mesh's own material or group name, or None.
    source: the file it came from.
    """

    mesh: trimesh.Trimesh
    name: str
    material: str | None
    source: Path
    #: (n_vertices, 2) texture coordinates (OpenGL convention: v up), or None
    uv: np.ndarray | None = None
    #: the base colour texture as PNG bytes, or None
    texture: bytes | None = None


def load_parts(path: Path, references: ReferencePolicy | None = None,
               triangles: Callable[[int, bool], None] | None = None) -> list[Part]:
    """Read ``path`` into a list of :class:`Part` (at least one, each non-empty).

    The input must be a readable regular file: a directory, a device (/dev/zero),
    a FIFO or a socket is refused before it is opened, so nothing blocks or reads
    forever; so must every file it refers to (an OBJ's MTL and textures, a .gltf's
    buffers and images), under ``references`` (:mod:`blastvox.io.references`: inside
    the mesh's folder by default). Every failure is a one-line :class:`MeshError`
    ``"<file>: <problem>"``. ``triangles(count, estimated)``, the caller's budget, is
    told how many triangles the file says it holds before it is parsed (at least that
    many) and how many it held once parsed; it raises to refuse.
    """
    path = Path(path)
    shown = printable(path)
    data = _read(path, whole=True)
    suffix = path.suffix.lower()
    if suffix == ".stl":
        _check_binary_stl(shown, data)
    elif suffix in (".gltf", ".glb"):
        doc = mesh_checks.gltf_document(shown, data)
        if doc is not None:
            mesh_checks.check_gltf_nodes(shown, doc)
    elif suffix == ".ply":
        mesh_checks.check_ply_counts(shown, data)
    if triangles is not None and (said := mesh_checks.triangle_estimate(suffix, data)):
        triangles(said, True)
    parts = (_load_volume(path) if suffix in VOLUME_SUFFIXES
             else _load_surface(path, data, references or ReferencePolicy()))
    parts = [p for p in parts if len(p.mesh.faces) > 0]
    if not parts:
        raise MeshError(f"{shown}: contains no triangles")
    if triangles is not None:
        triangles(sum(len(p.mesh.faces) for p in parts), False)
    for part in parts:
        if not np.all(np.isfinite(part.mesh.vertices)):
            raise MeshError(f"{shown}: part '{part.name}' has NaN or infinite vertex coordinates")
    return parts


def missing_textures(path: Path, policy: ReferencePolicy | None = None) -> list[str]:
    """One line per texture that ``path`` names but that is not there or that no image
    reader decodes (an OBJ's ``map_Kd`` in its .mtl files, a .gltf's image ``uri`` or
    ``data:`` URI, a .glb's embedded images): the loader drops those silently and the
    part keeps its base colour, so the caller warns. Textures are read under
    ``policy`` (default: inside the mesh's folder); what it refuses the loader has
    already refused."""
    policy = policy or ReferencePolicy()
    shown = printable(path)
    suffix = path.suffix.lower()
    missing: list[str] = []
    try:
        data = path.read_bytes() if suffix in (".obj", ".gltf", ".glb") else b""
    except OSError:
        return missing
    if suffix == ".obj":
        for line in data.decode("utf-8", errors="replace").splitlines():
            words = line.split(maxsplit=1)
            if len(words) == 2 and words[0] == "mtllib":
                missing += _missing_mtl_maps(path, words[1].strip(), shown, policy)
    elif suffix in (".gltf", ".glb"):
        with contextlib.suppress(ValueError, TypeError, AttributeError, KeyError,
                                 IndexError, RecursionError):
            doc, binary = _gltf_document(data, suffix)
            for image in doc.get("images", []):
                name = f"texture '{shortened(printable(image.get('uri', '')))}' of image " \
                    f"'{image.get('name', '')}'"
                problem = _image_problem(path, image, doc, binary, policy)
                if problem is not None:
                    missing.append(f"{shown}: {name} {problem}; the base colour is used")
    return missing


def _gltf_document(data: bytes, suffix: str) -> tuple[dict, bytes]:
    """A .gltf's or .glb's JSON and a .glb's binary chunk (b'' for a .gltf)."""
    if suffix == ".gltf":
        return json.loads(data.decode("utf-8")), b""
    length = int.from_bytes(data[12:16], "little")
    doc = json.loads(data[20:20 + length].decode("utf-8"))
    rest = data[20 + length:]
    binary = rest[8:8 + int.from_bytes(rest[:4], "little")] if len(rest) >= 8 else b""
    return doc, binary


def _image_problem(path: Path, image: dict, doc: dict, binary: bytes,
                   policy: ReferencePolicy) -> str | None:
    """Why the glTF ``image`` has no picture ('not found', 'cannot be decoded (...)'),
    or None if it decodes."""
    uri = image.get("uri")
    if isinstance(uri, str) and uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1], validate=True)
        except (IndexError, ValueError):
            return "is a malformed data: URI"
    elif isinstance(uri, str) and uri:
        try:
            data = read_uri(policy, path, uri)
        except FileNotFoundError:
            return "not found"
        except (OSError, InputError):
            return None  # refused: the loader has said why
    elif "bufferView" in image and binary:
        view = doc["bufferViews"][image["bufferView"]]
        start = int(view.get("byteOffset", 0))
        data = binary[start:start + int(view["byteLength"])]
    else:
        return None
    return _undecodable(data)


def _undecodable(data: bytes) -> str | None:
    """Why Pillow cannot decode the image ``data``, or None if it can (headers and
    checksums read, within Pillow's limit on pixels: a 20,000 x 20,000 PNG is refused
    before it is inflated)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as image:
                image.verify()
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        return f"cannot be decoded (more than {Image.MAX_IMAGE_PIXELS:,} pixels)"
    except UnidentifiedImageError:
        return "cannot be decoded (not an image format Pillow reads)"
    except Exception as exc:  # Pillow raises many kinds for a broken image
        return f"cannot be decoded ({shortened(printable(str(exc) or type(exc).__name__))})"
    return None


def _missing_mtl_maps(obj: Path, name: str, shown: str,
                      policy: ReferencePolicy) -> list[str]:
    mtl = obj.parent / name
    try:
        text = policy.read(obj, name).decode("utf-8", errors="replace")
    except FileNotFoundError:
        return [f"{shown}: material library '{shortened(printable(name))}' not found; the "
                "base colour is used"]
    except (OSError, InputError):
        return []  # refused: the loader has said why
    missing, material = [], ""
    for line in text.splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] == "newmtl":
            material = words[1]
        elif len(words) >= 2 and words[0].lower() == "map_kd":
            texture = words[-1]  # options such as -s come before the file name
            said = f"{shown}: texture '{shortened(printable(texture))}' of material " \
                f"'{material}'"
            try:
                problem = _undecodable(policy.read(mtl, texture))
            except FileNotFoundError:
                problem = "not found"
            except (OSError, InputError) as exc:
                problem = f"not read ({exc})" if isinstance(exc, InputError) else "not read"
            if problem is not None:
                missing.append(f"{said} {problem}; the base colour is used")
    return missing


def check_readable(path: Path) -> None:
    """Refuse, before any work, a mesh input that :func:`load_parts` could not read: missing,
    unreadable, empty, or not a regular file (see there). Opens it, reads nothing."""
    _read(Path(path), whole=False)


def _read(path: Path, whole: bool) -> bytes:
    shown = printable(path)
    try:
        if regular_file(path, "mesh file") == 0:
            raise MeshError(f"{shown}: file is empty")
        with open(path, "rb") as fh:
            return fh.read() if whole else b""
    except InputError as exc:
        raise MeshError(str(exc)) from None
    except FileNotFoundError:
        raise MeshError(f"{shown}: no such file") from None
    except OSError as exc:
        raise MeshError(f"{shown}: cannot read ({exc.strerror or exc})") from None


def _reason(exc: BaseException) -> str:
    text = str(exc).strip()
    return " ".join(text.splitlines()[0].split()) if text else type(exc).__name__


class _PolicyResolver(trimesh.resolvers.FilePathResolver):
    """trimesh's file resolver reading side files under a :class:`ReferencePolicy`. A
    refusal is kept in ``refused`` (shared with namespaced copies): trimesh skips a
    material it cannot read, and the caller turns the first refusal into the error."""

    def __init__(self, source: str, policy: ReferencePolicy, refused: list[str]) -> None:
        super().__init__(source, allow_anywhere=True)  # the policy judges, not trimesh
        self.policy, self.refused = policy, refused

    def get(self, name: str) -> bytes:
        source = Path(self.file_path)
        try:
            if source.suffix.lower() in (".gltf", ".glb"):  # a URI: percent-encoded
                return read_uri(self.policy, source, name)
            return self.policy.read(source, name)
        except ReferenceRefused as exc:
            self.refused.append(str(exc))
            raise

    def namespaced(self, namespace: str) -> _PolicyResolver:
        return _PolicyResolver(os.path.join(self.parent, namespace, self.file_name),
                               self.policy, self.refused)


def _trimesh_load(path: Path, data: bytes, policy: ReferencePolicy) -> trimesh.Scene:
    """trimesh's loader on bytes already read. The file name is passed as the file type
    (trimesh names nodes after it) and to the resolver (side files such as .mtl and
    .bin are read beside it, under ``policy``); a name that is not valid UTF-8 is passed
    in its printable form (trimesh cannot hash it), its side files are still found in
    its directory. A refused side file raises :class:`MeshError`."""
    name = printable(path)
    refused: list[str] = []
    resolver = _PolicyResolver(str(path.parent / printable(path.name)), policy, refused)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            loaded = trimesh.load(io.BytesIO(data), file_type=name, force="scene",
                                  process=False, resolver=resolver)
        except Exception:
            if refused:
                raise MeshError(refused[0]) from None
            raise
    if refused:
        raise MeshError(refused[0])
    return loaded


def _load_surface(path: Path, data: bytes, policy: ReferencePolicy) -> list[Part]:
    shown = printable(path)
    try:
        try:
            loaded = _trimesh_load(path, data, policy)
        except ModuleNotFoundError as exc:
            if exc.name != "charset_normalizer":
                raise
            # text that is not UTF-8: trimesh would guess its encoding with a package
            # we do not need; Latin-1 (the usual legacy one) decodes any byte
            loaded = _trimesh_load(path, data.decode("latin-1").encode("utf-8"), policy)
    except MeshError:
        raise
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise MeshError(f"{shown}: cannot read mesh ({_reason(exc)})") from None
    if not isinstance(loaded, trimesh.Scene):
        raise MeshError(f"{shown}: cannot read mesh (not a mesh file)")
    parts: list[Part] = []
    encoded: dict[int, bytes | None] = {}  # image id -> PNG: each image encoded once
    for name, node in _stable_nodes(loaded, path):
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh):
            continue  # point clouds and paths carry no volume
        _check_faces(shown, str(name), np.asarray(geom.faces), len(geom.vertices))
        mesh = trimesh.Trimesh(vertices=np.asarray(geom.vertices, dtype=np.float64),
                               faces=np.asarray(geom.faces), process=False)
        mesh.apply_transform(transform)
        material = getattr(getattr(geom.visual, "material", None), "name", None)
        uv, texture = _texture(geom, encoded)
        if texture is None:
            mesh, uv, texture = _baked_colors(geom, mesh)
        parts.append(Part(mesh=mesh, name=printable(str(name)), material=material,
                          source=path, uv=uv, texture=texture))
    return parts


def _check_binary_stl(shown: str, data: bytes) -> None:
    """Refuse a binary STL whose header's triangle count is not what the file holds
    (84 bytes of header and count, then 50 bytes a triangle): it said "contains no
    triangles" of a file holding 12. An ASCII STL (text from "solid") is left alone."""
    if len(data) < 84 or (data[:5].lower() == b"solid" and b"facet" in data[:1024]):
        return
    count = int.from_bytes(data[80:84], "little")
    held, rest = divmod(len(data) - 84, 50)
    if count != held and rest == 0:
        raise MeshError(f"{shown}: binary STL header says {count:,} triangles, but the file "
                        f"holds {held:,} ({len(data):,} bytes: 84 + 50 a triangle); "
                        "re-export it")


def _check_faces(shown: str, part: str, faces: np.ndarray, vertex_count: int) -> None:
    """Refuse a part whose faces name vertices it does not have (a PLY or glTF whose
    indices run past its vertex list: an IndexError deep in the voxelizer before)."""
    if faces.size and (faces.min() < 0 or faces.max() >= vertex_count):
        bad = int(faces.max()) if faces.max() >= vertex_count else int(faces.min())
        raise MeshError(f"{shown}: part {printable(part)!r}: a face names vertex {bad:,}, "
                        f"but the part has {vertex_count:,} vertices (0 to "
                        f"{vertex_count - 1:,})")


def _baked_colors(geom: trimesh.Trimesh, mesh: trimesh.Trimesh
                  ) -> tuple[trimesh.Trimesh, np.ndarray | None, bytes | None]:
    """A part coloured per vertex or per face: its colours baked into a texture
    (:mod:`blastvox.voxelize.vertex_colors`), with ``mesh`` split into three vertices per
    triangle so that each corner has its own UV (the solid is merged again for the
    inside test). Unchanged (mesh, None, None) without colours."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    corners = vertex_colors.corner_colors(geom.visual, faces)
    if corners is None:
        return mesh, None, None
    uv, png = vertex_colors.bake(corners)
    split = trimesh.Trimesh(vertices=np.asarray(mesh.vertices)[faces].reshape(-1, 3),
                            faces=np.arange(3 * len(faces)).reshape(-1, 3), process=False)
    return split, uv.reshape(-1, 2), png


#: trimesh names the node of each primitive of a multi-primitive glTF mesh
#: "<mesh index>_<6 random hex digits>": a different name on every load.
_GENERATED_NODE = re.compile(r"\d+_[0-9a-f]{6}")


def _stable_nodes(loaded: trimesh.Scene, path: Path) -> list[tuple[str, str]]:
    """(part name, node) of every geometry node, in an order and with names that are
    the same on every load: a generated node name is replaced by its geometry's name
    (the Cesium Milk Truck's glass was "0_3a8c99" once and "0_e67eb9" the next time,
    and sorting by it reordered the parts, so the same file gave different models)."""
    entries = []
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        name = str(geom_name) if _GENERATED_NODE.fullmatch(str(node)) else str(node)
        if name == path.name:
            name = path.stem
        entries.append((name, np.asarray(transform, dtype=np.float64).tobytes(), node))
    entries.sort(key=lambda e: (e[0], e[1]))
    return [(name, node) for name, _, node in entries]


def _texture(geom: trimesh.Trimesh, encoded: dict[int, bytes | None]
             ) -> tuple[np.ndarray | None, bytes | None]:
    """The mesh's per-vertex UVs and its base colour image as PNG bytes (glTF PBR
    ``baseColorTexture``, OBJ/MTL ``map_Kd``), or (None, None) when it has no textured
    look. PNG from Pillow is byte-deterministic, so the same input gives the same model.
    ``encoded`` memoizes the PNG of each image object (a file's parts and instances
    share images: the truck's body and wheels use one 2048 x 2048 atlas)."""
    visual = geom.visual
    uv = getattr(visual, "uv", None)
    material = getattr(visual, "material", None)
    image = getattr(material, "baseColorTexture", None)
    if image is None:
        image = getattr(material, "image", None)
    if uv is None or image is None or len(uv) != len(geom.vertices):
        return None, None
    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim != 2 or uv.shape[1] != 2 or not np.isfinite(uv).all():
        return None, None
    if id(image) not in encoded:
        encoded[id(image)] = _png(image)
    png = encoded[id(image)]
    return (uv, png) if png is not None else (None, None)


def _png(image) -> bytes | None:
    """``image`` (Pillow) as PNG bytes, or None if Pillow cannot decode it (the part
    then keeps its material colour)."""
    out = io.BytesIO()
    try:
        image.convert("RGBA" if "A" in image.getbands() else "RGB").save(out, format="PNG")
    except Exception:
        return None
    return out.getvalue()


def _load_volume(path: Path) -> list[Part]:
    import meshio

    shown = printable(path)
    said = io.StringIO()
    try:
        # meshio prints its reasons and, for a file none of its readers takes,
        # calls sys.exit inside the library: keep both from reaching the user
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said), \
                warnings.catch_warnings():
            warnings.simplefilter("ignore")
            vol = meshio.read(path)
    except SystemExit:
        lines = [line.strip() for line in said.getvalue().splitlines()
                 if line.strip() and "Couldn't read file" not in line]
        reason = lines[0] if lines else f"not a {path.suffix} file meshio can read"
        raise MeshError(f"{shown}: cannot read volume mesh ({printable(reason)})") from None
    except Exception as exc:
        raise MeshError(f"{shown}: cannot read volume mesh ({_reason(exc)})") from None
    points = np.asarray(vol.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise MeshError(f"{shown}: volume mesh points have shape {points.shape}; need (N, 3)")
    if points.shape[1] == 2:
        raise MeshError(f"{shown}: volume mesh is 2-D; need 3-D cells")
    faces = []
    for block in vol.cells:
        local = VTK_CELL_FACES.get(block.type)  # the cell's outward boundary triangles
        if local is None:
            continue
        data = np.asarray(block.data)
        if data.size and (data.min() < 0 or data.max() >= len(points)):
            raise MeshError(f"{shown}: {block.type} cells refer to points that are not in "
                            f"the file ({len(points)} points)")
        faces.append(data[:, local].reshape(-1, 3))
    if not faces:
        kinds = ", ".join(sorted({b.type for b in vol.cells})) or "none"
        raise MeshError(f"{shown}: no tetrahedra or hexahedra in volume mesh (cell types: {kinds})")
    all_faces = np.concatenate(faces)
    # A face shared by two cells is interior; boundary faces occur once.
    key = np.sort(all_faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = all_faces[counts[inverse.ravel()] == 1]
    mesh = trimesh.Trimesh(vertices=points, faces=boundary, process=False)
    mesh.remove_unreferenced_vertices()
    return [Part(mesh=mesh, name=printable(path.stem), material=None, source=path)]
