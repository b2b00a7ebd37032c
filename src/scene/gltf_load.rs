//! glTF 2.0 loading (`.gltf` with external or embedded buffers, and `.glb`).
//!
//! The loader does not use `gltf::import`: that fails a whole model when one
//! texture image is missing, and the `gltf` crate's own validation and
//! readers index arrays unchecked (a malformed file can make them panic).
//! Instead the JSON is deserialised into `gltf::json` structures and every
//! reference, byte range and value is checked here, so that
//!
//! - geometry problems (a missing or short buffer, a missing `POSITION`, an
//!   out-of-range index, a NaN or infinite vertex, an accessor running past
//!   its buffer view) are errors that name the file and the mesh;
//! - texture problems (a missing or undecodable image) are warnings, pushed to
//!   [`Scene::warnings`] and logged, and the geometry still loads;
//! - no input bytes can make the loader panic.
//!
//! Every primitive of every mesh node of the default scene (or the first
//! scene, or every root node when there is no scene) becomes one world-space
//! [`Mesh`] named `"<mesh name or mesh#i>/primitive#j"`.

use std::borrow::Cow;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{DMat4, DQuat, DVec2, DVec3};
use gltf::json;
use json::accessor::{ComponentType, Type};
use json::validation::Checked;

use super::{
    is_closed, split_closed_parts, weld, welded_triangles, AlphaMode, Camera, MagFilter, Material,
    Mesh, Sampler, Scene, Texture, Wrap,
};
use crate::light::{Distribution, Light, LightShape};
use crate::{Error, Result};

/// Accessors without a buffer view are zero-filled; this bounds their size
/// so that a tiny malformed file cannot ask for gigabytes.
const MAX_ZERO_FILLED_ELEMENTS: u64 = 1 << 22;

/// Image height of cameras read from glTF; the width follows the aspect ratio.
const CAMERA_HEIGHT: u32 = 512;

/// Whether a glTF extension listed in `extensionsRequired` can be honoured.
///
/// `KHR_mesh_quantization` is read (any component type, normalised or not);
/// material and light extensions do not change geometry or base-colour alpha
/// in a way shadows depend on.
fn required_extension_supported(name: &str) -> bool {
    name.starts_with("KHR_materials_")
        || matches!(name, "KHR_mesh_quantization" | "KHR_lights_punctual")
}

/// Loads a `.gltf` (external `.bin` files and images are resolved relative to
/// the file's folder) or `.glb` file into a world-space [`Scene`].
///
/// Errors are [`Error::Io`] when the file cannot be read and [`Error::Gltf`]
/// (displayed as `"path: message"`) for everything else.
pub fn load_gltf(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let base_dir = match path.parent() {
        Some(p) if p.as_os_str().is_empty() => Path::new("."),
        Some(p) => p,
        None => Path::new("."),
    };
    load(&bytes, Some(base_dir), path)
}

/// Loads glTF or GLB `bytes` held in memory.
///
/// External files (buffers, images) are resolved relative to `base_dir`;
/// without one they are reported as unresolvable. `name_for_errors` is the
/// path that errors and warnings name. This function never panics, whatever
/// the bytes.
pub fn load_gltf_slice(
    bytes: &[u8],
    base_dir: Option<&Path>,
    name_for_errors: &str,
) -> Result<Scene> {
    load(bytes, base_dir, Path::new(name_for_errors))
}

fn load(bytes: &[u8], base_dir: Option<&Path>, file: &Path) -> Result<Scene> {
    let gltf_err = |message: String| Error::Gltf {
        path: file.to_path_buf(),
        message,
    };
    if bytes.is_empty() {
        return Err(gltf_err("empty file".into()));
    }
    let (json_bytes, blob) = if bytes.starts_with(b"glTF") {
        split_glb(bytes).map_err(gltf_err)?
    } else {
        (bytes, None)
    };
    let json_bytes = json_bytes
        .strip_prefix(b"\xEF\xBB\xBF".as_slice())
        .unwrap_or(json_bytes);
    let root: json::Root = serde_json::from_slice(json_bytes)
        .map_err(|e| gltf_err(format!("not a valid glTF file: {e}")))?;
    if !root.asset.version.starts_with("2.") && root.asset.version != "2" {
        return Err(gltf_err(format!(
            "glTF version {:?} is not supported (only 2.x)",
            root.asset.version
        )));
    }
    for ext in &root.extensions_required {
        if !required_extension_supported(ext) {
            return Err(gltf_err(format!(
                "required extension {ext} is not supported \
                 (supported: KHR_mesh_quantization, KHR_lights_punctual, KHR_materials_*)"
            )));
        }
    }
    let mut loader = Loader::new(file, base_dir, &root, blob);
    // Warnings met before an error were logged; the error replaces the scene.
    let mut scene = loader.run().map_err(gltf_err)?;
    scene.warnings = std::mem::take(&mut loader.warnings);
    Ok(scene)
}

/// Reads a little-endian u32 at `at`, `None` when out of range.
fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// Splits a GLB container into its JSON chunk and optional BIN chunk.
fn split_glb(bytes: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), String> {
    if bytes.len() < 12 {
        return Err(format!(
            "truncated GLB: {} bytes, shorter than the 12-byte header",
            bytes.len()
        ));
    }
    let version = u32_at(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(format!(
            "GLB container version {version} is not supported (only 2)"
        ));
    }
    let length = u32_at(bytes, 8).unwrap_or(0) as usize;
    if length > bytes.len() {
        return Err(format!(
            "truncated GLB: the header says {length} bytes but the file has {}",
            bytes.len()
        ));
    }
    if length < 20 {
        return Err(format!(
            "invalid GLB: total length {length} leaves no room for a JSON chunk"
        ));
    }
    let data = &bytes[..length];
    let chunk = |pos: usize| -> std::result::Result<(usize, [u8; 4], usize), String> {
        let len = u32_at(data, pos).ok_or("truncated GLB chunk header")? as usize;
        let ty = data
            .get(pos + 4..pos + 8)
            .ok_or("truncated GLB chunk header")?;
        let start = pos + 8;
        let end = start
            .checked_add(len)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                format!(
                    "truncated GLB: a {}-byte {} chunk at byte {pos} runs past the end ({} bytes)",
                    len,
                    String::from_utf8_lossy(ty).trim_end_matches('\0'),
                    data.len()
                )
            })?;
        Ok((start, [ty[0], ty[1], ty[2], ty[3]], end))
    };
    let (start, ty, end) = chunk(12)?;
    if &ty != b"JSON" {
        return Err("invalid GLB: the first chunk is not JSON".into());
    }
    let json_chunk = &data[start..end];
    let mut bin = None;
    let mut pos = end;
    while pos + 8 <= data.len() {
        let (start, ty, end) = chunk(pos)?;
        if &ty == b"BIN\0" && bin.is_none() {
            bin = Some(&data[start..end]);
        }
        pos = end;
    }
    Ok((json_chunk, bin))
}

/// Decodes standard or URL-safe base64, ignoring whitespace and padding.
fn base64_decode(s: &str) -> std::result::Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    for (i, c) in s.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return Err(format!("invalid base64 character {:?} at {i}", c as char)),
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// Decodes `%XX` escapes (invalid escapes are kept as written).
fn percent_decode(s: &str) -> Vec<u8> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    out
}

/// Accessor data converted to f64 (normalised integers mapped to [0, 1] or
/// [-1, 1]), `components` values per element.
struct AccessorData {
    values: Vec<f64>,
    components: usize,
}

impl AccessorData {
    fn count(&self) -> usize {
        self.values.len() / self.components.max(1)
    }
}

/// Reads component `ct` at byte `at` of `b` (the caller checked the range).
fn read_component(b: &[u8], at: usize, ct: ComponentType, normalized: bool) -> f64 {
    let get = |k: usize| b.get(at + k).copied().unwrap_or(0);
    match ct {
        ComponentType::I8 => {
            let v = get(0) as i8 as f64;
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U8 => {
            let v = get(0) as f64;
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes([get(0), get(1)]) as f64;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes([get(0), get(1)]) as f64;
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        ComponentType::U32 => {
            let v = u32::from_le_bytes([get(0), get(1), get(2), get(3)]) as f64;
            if normalized {
                v / 4294967295.0
            } else {
                v
            }
        }
        ComponentType::F32 => f32::from_le_bytes([get(0), get(1), get(2), get(3)]) as f64,
    }
}

fn component_name(ct: ComponentType) -> &'static str {
    match ct {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

/// `first + stride * (count - 1) + elem`: the bytes `count` elements need, or
/// `None` on overflow; 0 for no elements.
fn bytes_needed(first: u64, stride: u64, count: u64, elem: u64) -> Option<u64> {
    if count == 0 {
        return Some(first);
    }
    stride
        .checked_mul(count - 1)?
        .checked_add(elem)?
        .checked_add(first)
}

type Msg = String;
type R<T> = std::result::Result<T, Msg>;

struct Loader<'a> {
    file: &'a Path,
    base_dir: Option<&'a Path>,
    root: &'a json::Root,
    /// Each buffer's bytes (cut to its `byteLength`) or why it is unusable;
    /// the error is raised only when geometry needs that buffer.
    buffers: Vec<R<Cow<'a, [u8]>>>,
    warnings: Vec<String>,
    /// Decoded base-colour images by image index.
    images: HashMap<usize, (String, Option<std::sync::Arc<image::RgbaImage>>)>,
    /// Images already checked for the "not needed but missing" warning.
    checked_unneeded: HashSet<usize>,
}

impl<'a> Loader<'a> {
    fn new(
        file: &'a Path,
        base_dir: Option<&'a Path>,
        root: &'a json::Root,
        blob: Option<&'a [u8]>,
    ) -> Self {
        let mut loader = Loader {
            file,
            base_dir,
            root,
            buffers: Vec::new(),
            warnings: Vec::new(),
            images: HashMap::new(),
            checked_unneeded: HashSet::new(),
        };
        let buffers = root
            .buffers
            .iter()
            .enumerate()
            .map(|(i, b)| loader.resolve_buffer(i, b, blob))
            .collect();
        loader.buffers = buffers;
        loader
    }

    fn warn(&mut self, msg: String) {
        let msg = format!("{}: {msg}", self.file.display());
        log::warn!("{msg}");
        self.warnings.push(msg);
    }

    /// Reads a URI: a `data:` URI or a file relative to the base folder.
    /// Returns the bytes or why they could not be read.
    fn read_uri(&self, uri: &str) -> R<Cow<'a, [u8]>> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let comma = rest
                .find(',')
                .ok_or_else(|| "malformed data URI (no ',')".to_string())?;
            let (header, payload) = (&rest[..comma], &rest[comma + 1..]);
            return if header.ends_with(";base64") {
                base64_decode(payload)
                    .map(Cow::Owned)
                    .map_err(|e| format!("malformed base64 data URI: {e}"))
            } else {
                Ok(Cow::Owned(percent_decode(payload)))
            };
        }
        if uri.contains("://") {
            return Err(format!(
                "URI {uri:?} is not supported (only relative files and data URIs)"
            ));
        }
        let path = self.uri_path(uri)?;
        let meta = std::fs::metadata(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        if !meta.is_file() {
            return Err(format!("{}: not a regular file", path.display()));
        }
        std::fs::read(&path)
            .map(Cow::Owned)
            .map_err(|e| format!("{}: {e}", path.display()))
    }

    /// The path of a relative file URI, resolved against the base folder.
    fn uri_path(&self, uri: &str) -> R<PathBuf> {
        let decoded = String::from_utf8(percent_decode(uri))
            .map_err(|_| format!("URI {uri:?} is not valid UTF-8 after percent-decoding"))?;
        match self.base_dir {
            Some(base) => Ok(base.join(decoded)),
            None => Err(format!(
                "external file {decoded:?} cannot be resolved (no base folder for in-memory input)"
            )),
        }
    }

    fn resolve_buffer(
        &self,
        i: usize,
        b: &json::Buffer,
        blob: Option<&'a [u8]>,
    ) -> R<Cow<'a, [u8]>> {
        let data: Cow<'a, [u8]> = match &b.uri {
            None if i == 0 => match blob {
                Some(bin) => Cow::Borrowed(bin),
                None => return Err("buffer 0 has no uri and the file has no GLB BIN chunk".into()),
            },
            None => {
                return Err(format!(
                    "buffer {i} has no uri (only buffer 0 may use the GLB BIN chunk)"
                ))
            }
            Some(uri) => {
                let what = if uri.starts_with("data:") {
                    "its data URI".to_string()
                } else {
                    format!("{uri:?}")
                };
                self.read_uri(uri)
                    .map_err(|e| format!("buffer {i} ({what}) cannot be read: {e}"))?
            }
        };
        let len = b.byte_length.0;
        if (data.len() as u64) < len {
            return Err(format!(
                "buffer {i} holds {} bytes but its byteLength is {len}",
                data.len()
            ));
        }
        let len = len as usize;
        Ok(match data {
            Cow::Borrowed(s) => Cow::Borrowed(&s[..len]),
            Cow::Owned(mut v) => {
                v.truncate(len);
                Cow::Owned(v)
            }
        })
    }

    /// The bytes of buffer view `vi` and its byte stride.
    fn view_bytes(&self, vi: usize) -> R<(&[u8], Option<usize>)> {
        let view = self
            .root
            .buffer_views
            .get(vi)
            .ok_or_else(|| format!("bufferView {vi} does not exist"))?;
        let bi = view.buffer.value();
        let buf = self
            .buffers
            .get(bi)
            .ok_or_else(|| format!("bufferView {vi} refers to buffer {bi}, which does not exist"))?
            .as_ref()
            .map_err(|e| e.clone())?;
        let off = view.byte_offset.map(|o| o.0).unwrap_or(0);
        let len = view.byte_length.0;
        let end = off
            .checked_add(len)
            .filter(|&e| e <= buf.len() as u64)
            .ok_or_else(|| {
                format!(
                    "bufferView {vi} (offset {off}, length {len}) runs past the end of buffer {bi} ({} bytes)",
                    buf.len()
                )
            })?;
        Ok((
            &buf[off as usize..end as usize],
            view.byte_stride.map(|s| s.0),
        ))
    }

    /// Reads accessor `ai` as f64 values (sparse accessors included).
    fn read_accessor(&self, ai: usize) -> R<AccessorData> {
        let acc = self
            .root
            .accessors
            .get(ai)
            .ok_or_else(|| format!("accessor {ai} does not exist"))?;
        let ct = match acc.component_type {
            Checked::Valid(json::accessor::GenericComponentType(ct)) => ct,
            Checked::Invalid => return Err(format!("accessor {ai} has an invalid componentType")),
        };
        let components = match acc.type_ {
            Checked::Valid(Type::Scalar) => 1,
            Checked::Valid(Type::Vec2) => 2,
            Checked::Valid(Type::Vec3) => 3,
            Checked::Valid(Type::Vec4) => 4,
            Checked::Valid(_) => {
                return Err(format!(
                    "accessor {ai}: matrix types are not supported here"
                ))
            }
            Checked::Invalid => return Err(format!("accessor {ai} has an invalid type")),
        };
        let count = acc.count.0;
        let csize = ct.size();
        let elem = csize * components;
        let mut values: Vec<f64>;
        match acc.buffer_view {
            Some(v) => {
                let vi = v.value();
                let (bytes, stride) = self.view_bytes(vi)?;
                let stride = stride.unwrap_or(elem);
                if stride < elem {
                    return Err(format!(
                        "accessor {ai}: byteStride {stride} of bufferView {vi} is smaller than one element ({elem} bytes)"
                    ));
                }
                let off = acc.byte_offset.map(|o| o.0).unwrap_or(0);
                let need = bytes_needed(off, stride as u64, count, elem as u64);
                if need.is_none_or(|n| n > bytes.len() as u64) {
                    return Err(format!(
                        "accessor {ai} ({count} x {} {}, offset {off}, stride {stride}) runs past the end of bufferView {vi} ({} bytes)",
                        components,
                        component_name(ct),
                        bytes.len()
                    ));
                }
                let (count, off) = (count as usize, off as usize);
                values = Vec::with_capacity(count * components);
                for i in 0..count {
                    let base = off + i * stride;
                    for c in 0..components {
                        values.push(read_component(bytes, base + c * csize, ct, acc.normalized));
                    }
                }
            }
            None => {
                if count > MAX_ZERO_FILLED_ELEMENTS {
                    return Err(format!(
                        "accessor {ai} has no bufferView and {count} elements (at most {MAX_ZERO_FILLED_ELEMENTS} supported)"
                    ));
                }
                values = vec![0.0; count as usize * components];
            }
        }
        if let Some(sparse) = &acc.sparse {
            let n = sparse.count.0;
            let ict = match sparse.indices.component_type {
                Checked::Valid(json::accessor::IndexComponentType(ct))
                    if matches!(
                        ct,
                        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                    ) =>
                {
                    ct
                }
                _ => {
                    return Err(format!(
                        "accessor {ai}: invalid sparse indices componentType"
                    ))
                }
            };
            let ivi = sparse.indices.buffer_view.value();
            let (ib, _) = self.view_bytes(ivi)?;
            let ioff = sparse.indices.byte_offset.0;
            let isz = ict.size() as u64;
            if bytes_needed(ioff, isz, n, isz).is_none_or(|need| need > ib.len() as u64) {
                return Err(format!(
                    "accessor {ai}: {n} sparse indices run past the end of bufferView {ivi}"
                ));
            }
            let vvi = sparse.values.buffer_view.value();
            let (vb, _) = self.view_bytes(vvi)?;
            let voff = sparse.values.byte_offset.0;
            if bytes_needed(voff, elem as u64, n, elem as u64)
                .is_none_or(|need| need > vb.len() as u64)
            {
                return Err(format!(
                    "accessor {ai}: {n} sparse values run past the end of bufferView {vvi}"
                ));
            }
            let (ioff, voff, isz) = (ioff as usize, voff as usize, isz as usize);
            for k in 0..n as usize {
                let idx = read_component(ib, ioff + k * isz, ict, false);
                if idx >= count as f64 {
                    return Err(format!(
                        "accessor {ai}: sparse index {idx} is out of range ({count} elements)"
                    ));
                }
                let idx = idx as usize;
                for c in 0..components {
                    values[idx * components + c] =
                        read_component(vb, voff + k * elem + c * csize, ct, acc.normalized);
                }
            }
        }
        Ok(AccessorData { values, components })
    }

    /// Reads an index accessor (unsigned integer scalars).
    fn read_indices(&self, ai: usize) -> R<Vec<u32>> {
        let acc = self
            .root
            .accessors
            .get(ai)
            .ok_or_else(|| format!("index accessor {ai} does not exist"))?;
        match acc.component_type {
            Checked::Valid(json::accessor::GenericComponentType(
                ComponentType::U8 | ComponentType::U16 | ComponentType::U32,
            )) => {}
            _ => {
                return Err(format!(
                    "index accessor {ai} must have an unsigned integer componentType"
                ))
            }
        }
        if acc.normalized {
            return Err(format!("index accessor {ai} must not be normalized"));
        }
        let data = self.read_accessor(ai)?;
        if data.components != 1 {
            return Err(format!("index accessor {ai} must be SCALAR"));
        }
        Ok(data.values.iter().map(|&v| v as u32).collect())
    }

    fn run(&mut self) -> R<Scene> {
        let root = self.root;
        let mut scene = Scene {
            materials: self.load_materials(),
            ..Scene::default()
        };

        // Root nodes to draw.
        let roots: Vec<usize> = match root.scene {
            Some(s) => root
                .scenes
                .get(s.value())
                .ok_or_else(|| format!("the default scene {} does not exist", s.value()))?
                .nodes
                .iter()
                .map(|n| n.value())
                .collect(),
            None if !root.scenes.is_empty() => {
                root.scenes[0].nodes.iter().map(|n| n.value()).collect()
            }
            None => {
                let mut is_child = vec![false; root.nodes.len()];
                for n in &root.nodes {
                    for c in n.children.iter().flatten() {
                        if let Some(f) = is_child.get_mut(c.value()) {
                            *f = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        };

        let mut visited = vec![false; root.nodes.len()];
        let mut stack: Vec<(usize, DMat4)> =
            roots.iter().rev().map(|&n| (n, DMat4::IDENTITY)).collect();
        while let Some((ni, parent)) = stack.pop() {
            let node = root
                .nodes
                .get(ni)
                .ok_or_else(|| format!("node {ni} does not exist"))?;
            let label = match &node.name {
                Some(n) => format!("node {ni} ({n:?})"),
                None => format!("node {ni}"),
            };
            if visited[ni] {
                return Err(format!(
                    "{label} is reached twice: the node hierarchy is not a tree"
                ));
            }
            visited[ni] = true;
            let world = parent * node_matrix(node).map_err(|e| format!("{label}: {e}"))?;
            if !world.is_finite() {
                return Err(format!("{label}: the world transform is not finite"));
            }
            if let Some(mi) = node.mesh {
                if node.skin.is_some() {
                    self.warn(format!(
                        "{label}: skinning is ignored (the mesh is used in its bind pose with the node transform)"
                    ));
                }
                self.load_mesh(mi.value(), &world, &scene.materials, &mut scene.meshes)?;
            }
            if let Some(ci) = node.camera {
                if let Some(cam) = self.load_camera(ci.value(), &world, &label) {
                    scene.cameras.push(cam);
                }
            }
            let light = node.extensions.as_ref();
            if let Some(l) = light.and_then(|e| e.khr_lights_punctual.as_ref()) {
                if let Some(light) = self.load_light(l.light.value(), &world, &label) {
                    scene.lights.push(light);
                }
            }
            for c in node.children.iter().flatten().rev() {
                stack.push((c.value(), world));
            }
        }
        Ok(scene)
    }

    fn load_mesh(
        &mut self,
        mi: usize,
        world: &DMat4,
        materials: &[Material],
        out: &mut Vec<Mesh>,
    ) -> R<()> {
        let root = self.root;
        let mesh = root
            .meshes
            .get(mi)
            .ok_or_else(|| format!("mesh {mi} does not exist"))?;
        let mesh_name = mesh.name.clone().unwrap_or_else(|| format!("mesh#{mi}"));
        if mesh.primitives.iter().any(|p| p.targets.is_some())
            && mesh.weights.iter().flatten().any(|&w| w != 0.0)
        {
            self.warn(format!("mesh {mesh_name:?}: morph targets are ignored"));
        }
        for (pj, prim) in mesh.primitives.iter().enumerate() {
            let name = format!("{mesh_name}/primitive#{pj}");
            if let Some(m) = self
                .load_primitive(prim, &name, world, materials)
                .map_err(|e| format!("mesh {name:?}: {e}"))?
            {
                out.extend(split_closed_parts(m));
            }
        }
        Ok(())
    }

    fn load_primitive(
        &mut self,
        prim: &json::mesh::Primitive,
        name: &str,
        world: &DMat4,
        materials: &[Material],
    ) -> R<Option<Mesh>> {
        use json::mesh::Mode;
        let mode = match prim.mode {
            Checked::Valid(m) => m,
            Checked::Invalid => return Err("invalid primitive mode".into()),
        };
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warn(format!(
                "mesh {name:?}: primitive mode {mode:?} is skipped (only triangles cast shadows)"
            ));
            return Ok(None);
        }
        let positions = self.read_positions(prim)?;
        let n = positions.len();

        let indices: Vec<u32> = match prim.indices {
            Some(ia) => {
                let idx = self
                    .read_indices(ia.value())
                    .map_err(|e| format!("indices: {e}"))?;
                if let Some(k) = idx.iter().position(|&i| i as usize >= n) {
                    return Err(format!(
                        "index {} (at position {k} of accessor {}) is out of range: {n} vertices",
                        idx[k],
                        ia.value()
                    ));
                }
                idx
            }
            None => (0..n as u32).collect(),
        };
        let triangles = triangulate(mode, &indices);
        if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
            self.warn(format!(
                "mesh {name:?}: {} indices are not a multiple of 3; the last {} are ignored",
                indices.len(),
                indices.len() % 3
            ));
        }
        if triangles.is_empty() {
            return Ok(None);
        }

        let uvs = self.read_uvs(prim, n)?;
        let normals = self.read_normals(prim, n)?;

        let material = match prim.material {
            Some(m) if m.value() < materials.len() => Some(m.value()),
            Some(m) => return Err(format!("material {} does not exist", m.value())),
            None => None,
        };
        if let Some(m) = material.map(|m| &materials[m]) {
            let textured = m
                .base_color_texture
                .as_ref()
                .is_some_and(|t| t.image.is_some());
            if m.alpha_mode != AlphaMode::Opaque && textured && uvs.is_none() {
                self.warn(format!(
                    "mesh {name:?}: material {:?} is alpha-tested but the mesh has no TEXCOORD_0: it casts as opaque",
                    m.name
                ));
            }
        }

        let mut mesh = Mesh {
            name: name.to_string(),
            positions,
            uvs,
            normals,
            indices: triangles,
            material,
            closed: false,
        };
        mesh.transform(world);
        if let Some(k) = mesh.positions.iter().position(|p| !p.is_finite()) {
            return Err(format!("vertex {k} is not finite after the node transform"));
        }
        mesh.closed = welded_is_closed(&mesh.positions, &mesh.indices);
        Ok(Some(mesh))
    }

    /// A primitive's POSITION attribute: VEC3, FLOAT (or quantized with
    /// `KHR_mesh_quantization`), every vertex finite.
    fn read_positions(&mut self, prim: &json::mesh::Primitive) -> R<Vec<DVec3>> {
        use json::mesh::Semantic;
        let pos_acc = prim
            .attributes
            .get(&Checked::Valid(Semantic::Positions))
            .ok_or("the primitive has no POSITION attribute")?
            .value();
        let pos = self
            .read_accessor(pos_acc)
            .map_err(|e| format!("POSITION: {e}"))?;
        if pos.components != 3 {
            return Err(format!(
                "POSITION accessor {pos_acc} must be VEC3, it has {} components",
                pos.components
            ));
        }
        // glTF 2.0 §3.7.2.1: positions are FLOAT; KHR_mesh_quantization
        // adds (normalized or not) BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT.
        if let Some(Checked::Valid(json::accessor::GenericComponentType(ct))) =
            self.root.accessors.get(pos_acc).map(|a| a.component_type)
        {
            let quantized = self
                .root
                .extensions_used
                .iter()
                .chain(&self.root.extensions_required)
                .any(|e| e == "KHR_mesh_quantization");
            let allowed = match ct {
                ComponentType::F32 => true,
                ComponentType::I8 | ComponentType::U8 | ComponentType::I16 | ComponentType::U16 => {
                    quantized
                }
                ComponentType::U32 => false,
            };
            if !allowed {
                return Err(format!(
                    "POSITION accessor {pos_acc} has componentType {}; positions must be FLOAT \
                     (or BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT with KHR_mesh_quantization)",
                    component_name(ct)
                ));
            }
        }
        let n = pos.count();
        if n > u32::MAX as usize {
            return Err(format!("{n} vertices are too many"));
        }
        let mut positions = Vec::with_capacity(n);
        for (k, p) in pos.values.chunks_exact(3).enumerate() {
            let v = DVec3::new(p[0], p[1], p[2]);
            if !v.is_finite() {
                return Err(format!(
                    "vertex {k} is not finite: [{}, {}, {}]",
                    v.x, v.y, v.z
                ));
            }
            positions.push(v);
        }
        Ok(positions)
    }

    /// A primitive's NORMAL attribute, when present: VEC3, one per vertex
    /// (`n`). For shading only: a non-finite or zero normal is a warning
    /// and the mesh's normals are dropped (the shading generates them).
    fn read_normals(&mut self, prim: &json::mesh::Primitive, n: usize) -> R<Option<Vec<DVec3>>> {
        use json::mesh::Semantic;
        let Some(na) = prim.attributes.get(&Checked::Valid(Semantic::Normals)) else {
            return Ok(None);
        };
        let acc = self
            .read_accessor(na.value())
            .map_err(|e| format!("NORMAL: {e}"))?;
        if acc.components != 3 || acc.count() != n {
            return Err(format!(
                "NORMAL accessor {} must be VEC3 with one element per vertex ({n}); it has {} \
                 components and {} elements",
                na.value(),
                acc.components,
                acc.count()
            ));
        }
        let normals: Vec<DVec3> = acc
            .values
            .chunks_exact(3)
            .map(|v| DVec3::new(v[0], v[1], v[2]))
            .collect();
        if let Some(k) = normals
            .iter()
            .position(|v| !v.is_finite() || v.length_squared() == 0.0)
        {
            self.warn(format!(
                "NORMAL accessor {}: normal {k} is zero or not finite; shading normals are \
                 generated instead",
                na.value()
            ));
            return Ok(None);
        }
        Ok(Some(normals))
    }

    /// A primitive's TEXCOORD_0 attribute, when present: VEC2, one per
    /// vertex (`n`), every value finite.
    fn read_uvs(&mut self, prim: &json::mesh::Primitive, n: usize) -> R<Option<Vec<DVec2>>> {
        use json::mesh::Semantic;
        Ok(
            match prim.attributes.get(&Checked::Valid(Semantic::TexCoords(0))) {
                None => None,
                Some(ua) => {
                    let uv = self
                        .read_accessor(ua.value())
                        .map_err(|e| format!("TEXCOORD_0: {e}"))?;
                    if uv.components != 2 {
                        return Err(format!("TEXCOORD_0 accessor {} must be VEC2", ua.value()));
                    }
                    if uv.count() != n {
                        return Err(format!(
                            "TEXCOORD_0 has {} elements but POSITION has {n}",
                            uv.count()
                        ));
                    }
                    if uv.values.iter().any(|v| !v.is_finite()) {
                        return Err("TEXCOORD_0 has a non-finite value".into());
                    }
                    Some(
                        uv.values
                            .chunks_exact(2)
                            .map(|c| DVec2::new(c[0], c[1]))
                            .collect::<Vec<_>>(),
                    )
                }
            },
        )
    }

    fn load_camera(&mut self, ci: usize, world: &DMat4, label: &str) -> Option<Camera> {
        use json::camera::Type as CamType;
        let root = self.root;
        let Some(cam) = root.cameras.get(ci) else {
            self.warn(format!("{label}: camera {ci} does not exist; skipped"));
            return None;
        };
        let cam_name = cam.name.clone().unwrap_or_else(|| format!("camera#{ci}"));
        let persp = match (&cam.type_, &cam.perspective) {
            (Checked::Valid(CamType::Perspective), Some(p)) => p,
            (Checked::Valid(CamType::Orthographic), _) => {
                self.warn(format!(
                    "camera {cam_name:?} is orthographic; only perspective cameras are supported, skipped"
                ));
                return None;
            }
            _ => {
                self.warn(format!("camera {cam_name:?} is malformed; skipped"));
                return None;
            }
        };
        let eye = world.w_axis.truncate();
        let forward = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y);
        let aspect = persp.aspect_ratio.map(|a| a as f64);
        let width = match aspect {
            Some(a) if a.is_finite() && a > 0.0 => {
                (CAMERA_HEIGHT as f64 * a).round().clamp(1.0, 16384.0) as u32
            }
            _ => CAMERA_HEIGHT,
        };
        let camera = Camera {
            eye,
            target: eye + forward,
            up,
            fov_y_deg: (persp.yfov as f64).to_degrees(),
            width,
            height: CAMERA_HEIGHT,
        };
        if let Err(e) = camera.validate() {
            self.warn(format!(
                "camera {cam_name:?} ({label}) is unusable ({e}); skipped"
            ));
            return None;
        }
        Some(camera)
    }

    /// A `KHR_lights_punctual` light placed by the node's `world` transform:
    /// point at its origin, directional along its -z; a spot light is a
    /// point light (its cone is not applied: a warning says so). The colour
    /// is kept; the photometric intensity is not (pictures are normalized,
    /// visibility does not depend on it).
    fn load_light(&mut self, li: usize, world: &DMat4, label: &str) -> Option<Light> {
        use json::extensions::scene::khr_lights_punctual::Type as LightType;
        let lights = self.root.extensions.as_ref()?.khr_lights_punctual.as_ref();
        let Some(l) = lights.and_then(|ls| ls.lights.get(li)) else {
            self.warn(format!("{label}: light {li} does not exist; skipped"));
            return None;
        };
        let name = l.name.clone().unwrap_or_else(|| format!("light#{li}"));
        let position = world.w_axis.truncate();
        let direction = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
        let shape = match l.type_ {
            Checked::Valid(LightType::Point) => LightShape::Point { position },
            Checked::Valid(LightType::Spot) => {
                self.warn(format!(
                    "spot light {name:?} ({label}) is used as a point light: its cone is not applied"
                ));
                LightShape::Point { position }
            }
            Checked::Valid(LightType::Directional) if direction != DVec3::ZERO => {
                LightShape::Directional { direction }
            }
            _ => {
                self.warn(format!("light {name:?} ({label}) is malformed; skipped"));
                return None;
            }
        };
        let color = l.color;
        if !position.is_finite() || color.iter().any(|c| !c.is_finite() || *c < 0.0) {
            self.warn(format!("light {name:?} ({label}) is not finite; skipped"));
            return None;
        }
        Some(Light {
            shape,
            samples: 1,
            distribution: Distribution::Poisson,
            seed: 7,
            color,
            intensity: 1.0,
            emission: None,
            per_pixel_rotation: false,
        })
    }

    fn load_materials(&mut self) -> Vec<Material> {
        let root = self.root;
        let mut out = Vec::with_capacity(root.materials.len());
        for (i, m) in root.materials.iter().enumerate() {
            let name = m.name.clone().unwrap_or_else(|| format!("material#{i}"));
            let alpha_mode = match m.alpha_mode {
                Checked::Valid(json::material::AlphaMode::Opaque) => AlphaMode::Opaque,
                Checked::Valid(json::material::AlphaMode::Mask) => AlphaMode::Mask,
                Checked::Valid(json::material::AlphaMode::Blend) => AlphaMode::Blend,
                Checked::Invalid => {
                    self.warn(format!(
                        "material {name:?}: invalid alphaMode, using OPAQUE"
                    ));
                    AlphaMode::Opaque
                }
            };
            let alpha_cutoff = m.alpha_cutoff.map(|c| c.0).unwrap_or(0.5);
            let pbr = &m.pbr_metallic_roughness;
            let base_color_texture = pbr
                .base_color_texture
                .as_ref()
                .and_then(|info| self.base_color_texture(&name, info.index.value()));
            // Textures that shadows never need: only check that they exist.
            let unneeded = [
                pbr.metallic_roughness_texture
                    .as_ref()
                    .map(|t| t.index.value()),
                m.normal_texture.as_ref().map(|t| t.index.value()),
                m.occlusion_texture.as_ref().map(|t| t.index.value()),
                m.emissive_texture.as_ref().map(|t| t.index.value()),
            ];
            for ti in unneeded.into_iter().flatten() {
                self.check_unneeded_texture(ti);
            }
            let material = Material {
                name,
                alpha_mode,
                alpha_cutoff,
                base_color_factor: pbr.base_color_factor.0,
                base_color_texture,
            };
            self.warn_alpha(&material, pbr.base_color_texture.as_ref());
            out.push(material);
        }
        out
    }

    /// Says how an alpha-blended or alpha-masked material casts when that
    /// is not what its file asks for.
    fn warn_alpha(&mut self, m: &Material, info: Option<&json::texture::Info>) {
        let name = &m.name;
        if m.alpha_mode == AlphaMode::Blend {
            self.warn(format!(
                "material {name:?}: BLEND is cast and seen as MASK with alphaCutoff 0.5 (shadows are opaque or not)"
            ));
        }
        if m.alpha_mode == AlphaMode::Opaque {
            return;
        }
        if m.base_color_texture
            .as_ref()
            .is_some_and(|t| t.image.is_none())
        {
            self.warn(format!(
                "material {name:?}: its base-colour texture is missing, so its alpha test is off: it casts as opaque"
            ));
        }
        if let Some(info) = info {
            if info.tex_coord != 0 {
                self.warn(format!(
                    "material {name:?}: the alpha test reads TEXCOORD_0, not TEXCOORD_{} as the texture asks",
                    info.tex_coord
                ));
            }
        }
    }

    fn base_color_texture(&mut self, material: &str, ti: usize) -> Option<Texture> {
        let root = self.root;
        let Some(tex) = root.textures.get(ti) else {
            self.warn(format!(
                "material {material:?}: base-colour texture {ti} does not exist; ignored"
            ));
            return None;
        };
        let ii = tex.source.value();
        if root.images.get(ii).is_none() {
            self.warn(format!(
                "material {material:?}: texture {ti} refers to image {ii}, which does not exist; ignored"
            ));
            return None;
        }
        if !self.images.contains_key(&ii) {
            let (source, result) = self.load_image(ii);
            let image = match result {
                Ok(img) => Some(std::sync::Arc::new(img)),
                Err(e) => {
                    self.warn(format!(
                        "material {material:?}: base-colour texture {source} {e}; only the baseColorFactor is used"
                    ));
                    None
                }
            };
            self.images.insert(ii, (source, image));
        }
        let (source, image) = self.images.get(&ii)?.clone();
        let sampler = self.sampler(material, tex.sampler.map(|s| s.value()));
        Some(Texture {
            source,
            image,
            sampler,
        })
    }

    /// The sampler of a texture (glTF's defaults when it names none).
    fn sampler(&mut self, material: &str, si: Option<usize>) -> Sampler {
        use json::texture::{MagFilter as Mag, WrappingMode as W};
        let Some(si) = si else {
            return Sampler::default();
        };
        let Some(s) = self.root.samplers.get(si) else {
            self.warn(format!(
                "material {material:?}: sampler {si} does not exist; using LINEAR and REPEAT"
            ));
            return Sampler::default();
        };
        let wrap = |w: &Checked<W>| match w {
            Checked::Valid(W::ClampToEdge) => Wrap::ClampToEdge,
            Checked::Valid(W::MirroredRepeat) => Wrap::MirroredRepeat,
            _ => Wrap::Repeat,
        };
        Sampler {
            mag_filter: match s.mag_filter {
                Some(Checked::Valid(Mag::Nearest)) => MagFilter::Nearest,
                _ => MagFilter::Linear,
            },
            wrap_s: wrap(&s.wrap_s),
            wrap_t: wrap(&s.wrap_t),
        }
    }

    /// Loads and decodes image `ii`: (source description, image or what failed).
    fn load_image(&self, ii: usize) -> (String, R<image::RgbaImage>) {
        let Some(img) = self.root.images.get(ii) else {
            return (format!("image#{ii}"), Err("does not exist".into()));
        };
        let (source, bytes) = match (&img.uri, &img.buffer_view) {
            (Some(uri), _) if uri.starts_with("data:") => (
                "embedded (data URI)".to_string(),
                self.read_uri(uri)
                    .map_err(|e| format!("could not be read: {e}")),
            ),
            (Some(uri), _) => match self.uri_path(uri) {
                Ok(path) if !path.exists() => (path.display().to_string(), Err("not found".into())),
                Ok(path) => (
                    path.display().to_string(),
                    self.read_uri(uri)
                        .map_err(|e| format!("could not be read ({e})")),
                ),
                Err(e) => (uri.clone(), Err(format!("could not be read ({e})"))),
            },
            (None, Some(v)) => (
                format!("embedded (bufferView {})", v.value()),
                self.view_bytes(v.value())
                    .map(|(b, _)| Cow::Borrowed(b))
                    .map_err(|e| format!("could not be read: {e}")),
            ),
            (None, None) => (
                format!("image#{ii}"),
                Err("has neither a uri nor a bufferView".to_string()),
            ),
        };
        let decoded = bytes.and_then(|b| {
            image::ImageReader::new(std::io::Cursor::new(&b[..]))
                .with_guessed_format()
                .map_err(|e| format!("could not be decoded: {e}"))?
                .decode()
                .map(|d| d.to_rgba8())
                .map_err(|e| format!("could not be decoded: {e}"))
        });
        (source, decoded)
    }

    /// Warns once per image when a texture shadows do not need is a missing file.
    fn check_unneeded_texture(&mut self, ti: usize) {
        let root = self.root;
        let Some(tex) = root.textures.get(ti) else {
            return;
        };
        let ii = tex.source.value();
        if !self.checked_unneeded.insert(ii) {
            return;
        }
        let Some(uri) = root.images.get(ii).and_then(|i| i.uri.as_ref()) else {
            return;
        };
        if uri.starts_with("data:") || uri.contains("://") {
            return;
        }
        if let Ok(path) = self.uri_path(uri) {
            if !path.is_file() {
                self.warn(format!(
                    "texture {} not found; shadows do not need it",
                    path.display()
                ));
            }
        }
    }
}

/// A node's local transform (matrix, or translation * rotation * scale).
fn node_matrix(node: &json::Node) -> R<DMat4> {
    if let Some(m) = node.matrix {
        let m = DMat4::from_cols_array(&m.map(|v| v as f64));
        if !m.is_finite() {
            return Err("the matrix is not finite".into());
        }
        return Ok(m);
    }
    let t = node.translation.unwrap_or([0.0; 3]).map(|v| v as f64);
    let s = node.scale.unwrap_or([1.0; 3]).map(|v| v as f64);
    let r = node.rotation.map(|q| q.0).unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let q = DQuat::from_xyzw(r[0] as f64, r[1] as f64, r[2] as f64, r[3] as f64);
    let len = q.length();
    if !(len.is_finite() && len > 0.0) {
        return Err(format!("invalid rotation quaternion {r:?}"));
    }
    let m = DMat4::from_scale_rotation_translation(DVec3::from(s), q / len, DVec3::from(t));
    if !m.is_finite() {
        return Err("the transform is not finite".into());
    }
    Ok(m)
}

/// Turns a primitive's index list into triangles (glTF 2.0 §3.7.2.1 vertex
/// orders). Strip and fan triangles that repeat an index (restart
/// degenerates) are dropped; listed triangles are kept as they are.
fn triangulate(mode: json::mesh::Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    use json::mesh::Mode;
    let degenerate = |t: &[u32; 3]| t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
    match mode {
        Mode::Triangles => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| {
                if i.is_multiple_of(2) {
                    [idx[i], idx[i + 1], idx[i + 2]]
                } else {
                    [idx[i], idx[i + 2], idx[i + 1]]
                }
            })
            .filter(|t| !degenerate(t))
            .collect(),
        Mode::TriangleFan => (1..idx.len().saturating_sub(1))
            .map(|i| [idx[i], idx[i + 1], idx[0]])
            .filter(|t| !degenerate(t))
            .collect(),
        _ => Vec::new(),
    }
}

/// [`is_closed`] on indices welded by exact position equality: every vertex
/// maps to the first vertex with a bit-identical position (glTF models
/// duplicate vertices along UV seams). Triangles that collapse after welding
/// have no area and are left out of the test.
pub(crate) fn welded_is_closed(positions: &[DVec3], indices: &[[u32; 3]]) -> bool {
    is_closed(&welded_triangles(&weld(positions), indices))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_values() {
        assert_eq!(base64_decode("TWFu").unwrap(), b"Man");
        assert_eq!(base64_decode("TWE=").unwrap(), b"Ma");
        assert_eq!(base64_decode("TQ==").unwrap(), b"M");
        assert!(base64_decode("T*==").is_err());
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b%zz%4"), b"a b%zz%4");
    }

    #[test]
    fn strips_follow_the_spec_order() {
        use json::mesh::Mode;
        assert_eq!(
            triangulate(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [1, 3, 2]]
        );
        assert_eq!(
            triangulate(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[1, 2, 0], [2, 3, 0]]
        );
    }
}
