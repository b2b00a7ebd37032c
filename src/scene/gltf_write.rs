//! Writing a [`Scene`] as one binary glTF 2.0 file (`.glb`).
//!
//! Each non-empty [`Mesh`](super::Mesh) becomes one glTF mesh with one triangle primitive
//! on its own node with the identity transform: positions as `f32` (the
//! scene's `f64` precision is lost, which is fine for the built-in scenes),
//! `u32` indices and `TEXCOORD_0` when the mesh has texture coordinates.
//! Materials keep `alphaMode`, `alphaCutoff` and `baseColorFactor`; a decoded
//! base-colour texture is embedded as PNG in the binary chunk. Cameras and
//! lights are not stored.

use std::path::Path;

use serde_json::{json, Value};

use super::{AlphaMode, Scene};
use crate::{Error, Result};

const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The binary chunk under construction and the JSON arrays that describe it.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Appends `bytes` (4-byte aligned) as a buffer view; returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, mut a: Value, bytes: &[u8], target: u32) -> usize {
        a["bufferView"] = json!(self.view(bytes, Some(target)));
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

/// Writes `scene` to `path` as a self-contained `.glb` (see the module
/// documentation for what is kept). Meshes without triangles are skipped.
///
/// Errors: [`Error::Gltf`] naming the mesh when a position does not fit in
/// `f32` or the file would exceed the GLB size limit, [`Error::Io`] when
/// writing fails.
pub fn write_glb(scene: &Scene, path: &Path) -> Result<()> {
    let bytes = glb_bytes(scene).map_err(|message| Error::Gltf {
        path: path.to_path_buf(),
        message,
    })?;
    std::fs::write(path, bytes).map_err(|e| Error::io(path, e))
}

fn glb_bytes(scene: &Scene) -> std::result::Result<Vec<u8>, String> {
    let mut b = Builder::default();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for mesh in &scene.meshes {
        if mesh.indices.is_empty() || mesh.positions.is_empty() {
            continue;
        }
        let mut pos = Vec::with_capacity(mesh.positions.len() * 12);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for (k, p) in mesh.positions.iter().enumerate() {
            let v = [p.x as f32, p.y as f32, p.z as f32];
            if v.iter().any(|c| !c.is_finite()) {
                return Err(format!(
                    "mesh {:?}: vertex {k} {p:?} is not representable as f32",
                    mesh.name
                ));
            }
            for c in 0..3 {
                lo[c] = lo[c].min(v[c]);
                hi[c] = hi[c].max(v[c]);
                pos.extend_from_slice(&v[c].to_le_bytes());
            }
        }
        let n = mesh.positions.len();
        let pos_acc = b.accessor(
            json!({"componentType": FLOAT, "count": n, "type": "VEC3", "min": lo, "max": hi}),
            &pos,
            ARRAY_BUFFER,
        );
        let mut attributes = json!({ "POSITION": pos_acc });
        if let Some(uvs) = mesh.uvs.as_ref().filter(|u| u.len() == n) {
            let mut bytes = Vec::with_capacity(n * 8);
            for uv in uvs {
                bytes.extend_from_slice(&(uv.x as f32).to_le_bytes());
                bytes.extend_from_slice(&(uv.y as f32).to_le_bytes());
            }
            attributes["TEXCOORD_0"] = json!(b.accessor(
                json!({"componentType": FLOAT, "count": n, "type": "VEC2"}),
                &bytes,
                ARRAY_BUFFER,
            ));
        }
        let mut idx = Vec::with_capacity(mesh.indices.len() * 12);
        for t in &mesh.indices {
            for &i in t {
                if i as usize >= n {
                    return Err(format!(
                        "mesh {:?}: index {i} is out of range ({n} vertices)",
                        mesh.name
                    ));
                }
                idx.extend_from_slice(&i.to_le_bytes());
            }
        }
        let idx_acc = b.accessor(
            json!({"componentType": UNSIGNED_INT, "count": mesh.indices.len() * 3, "type": "SCALAR"}),
            &idx,
            ELEMENT_ARRAY_BUFFER,
        );
        let mut prim = json!({"attributes": attributes, "indices": idx_acc, "mode": 4});
        if let Some(m) = mesh.material.filter(|&m| m < scene.materials.len()) {
            prim["material"] = json!(m);
        }
        nodes.push(json!({"mesh": meshes.len(), "name": mesh.name}));
        meshes.push(json!({"name": mesh.name, "primitives": [prim]}));
    }

    let (materials, textures, images) = write_materials(&mut b, scene)?;

    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    let mut root = json!({
        "asset": {"version": "2.0", "generator": "alias-free-shadows"},
        "scene": 0,
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
    });
    let obj = root.as_object_mut().expect("a JSON object");
    let mut put = |key: &str, v: Vec<Value>| {
        if !v.is_empty() {
            obj.insert(key.into(), Value::Array(v));
        }
    };
    put("meshes", meshes);
    put("materials", materials);
    if !textures.is_empty() {
        // Nearest filtering keeps alpha-mask texels crisp in other viewers.
        put(
            "samplers",
            vec![json!({"magFilter": 9728, "minFilter": 9728})],
        );
    }
    put("textures", textures);
    put("images", images);
    put("accessors", b.accessors);
    put("bufferViews", b.views);
    if !b.bin.is_empty() {
        put("buffers", vec![json!({"byteLength": b.bin.len()})]);
    }

    let json_bytes = serde_json::to_vec(&root).map_err(|e| e.to_string())?;
    glb_container(json_bytes, &b.bin)
}

/// The GLB container: header, the JSON chunk (padded with spaces) and the
/// binary chunk when there is one (`bin` already padded to 4 bytes).
fn glb_container(mut json_bytes: Vec<u8>, bin: &[u8]) -> std::result::Result<Vec<u8>, String> {
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total32 =
        u32::try_from(total).map_err(|_| format!("{total} bytes exceed the GLB limit of 4 GiB"))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
    }
    Ok(out)
}

/// The glTF `materials`, `textures` and `images` arrays.
type MaterialArrays = (Vec<Value>, Vec<Value>, Vec<Value>);

/// The scene's materials, with their base-colour textures as PNG images in
/// the binary chunk.
fn write_materials(b: &mut Builder, scene: &Scene) -> std::result::Result<MaterialArrays, String> {
    let mut materials = Vec::new();
    let mut textures = Vec::new();
    let mut images = Vec::new();
    for (mi, m) in scene.materials.iter().enumerate() {
        let mut pbr = json!({
            "baseColorFactor": m.base_color_factor,
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        });
        if let Some(img) = m.base_color_texture.as_ref().and_then(|t| t.image.as_ref()) {
            let mut png = std::io::Cursor::new(Vec::new());
            img.write_to(&mut png, image::ImageFormat::Png)
                .map_err(|e| format!("material {:?} (#{mi}): PNG encoding failed: {e}", m.name))?;
            let view = b.view(png.get_ref(), None);
            images.push(json!({"bufferView": view, "mimeType": "image/png"}));
            textures.push(json!({"source": images.len() - 1, "sampler": 0}));
            pbr["baseColorTexture"] = json!({"index": textures.len() - 1});
        }
        let mut mat = json!({"name": m.name, "pbrMetallicRoughness": pbr, "doubleSided": true});
        match m.alpha_mode {
            AlphaMode::Opaque => {}
            AlphaMode::Mask => {
                mat["alphaMode"] = json!("MASK");
                mat["alphaCutoff"] = json!(m.alpha_cutoff);
            }
            AlphaMode::Blend => mat["alphaMode"] = json!("BLEND"),
        }
        materials.push(mat);
    }
    Ok((materials, textures, images))
}
