//! glTF and GLB bytes through the loader (`load_gltf_slice`, from memory:
//! no base folder, so no file I/O), then what `afs` does with a loaded
//! scene before rendering: the flattened triangles, the alpha tests'
//! tables, the shading normals, the default camera and light, the range
//! check against that camera and the triangles in GPU form seen from it.
#![no_main]

use alias_free_shadows::cpu::alpha::AlphaTables;
use alias_free_shadows::render::inputs::gpu_triangles;
use alias_free_shadows::scene::{file, gltf_load};
use alias_free_shadows::shade::ShadingNormals;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") {
        "fuzz.glb"
    } else {
        "fuzz.gltf"
    };
    match gltf_load::load_gltf_slice(data, None, name) {
        Ok(scene) => {
            // Indices were checked: flattening cannot index out of range.
            let triangles = scene.triangles();
            assert_eq!(triangles.len(), scene.triangle_count());
            for t in &triangles {
                assert!(t.vertices.iter().all(|v| v.is_finite()));
            }
            let alpha = AlphaTables::new(&scene);
            assert!(alpha.is_empty() || alpha.triangle_records.len() == triangles.len());
            for c in &scene.cameras {
                c.validate().expect("cameras the loader keeps are valid");
            }
            let normals = ShadingNormals::new(&scene);
            assert_eq!(normals.triangle_count(), triangles.len());
            let (camera, light) = file::default_view(&scene);
            if scene.validate(camera.eye).is_ok() {
                assert_eq!(gpu_triangles(&scene, camera.eye).len(), triangles.len());
            }
            let _ = light.validate();
        }
        Err(e) => {
            let m = e.to_string();
            assert!(m.starts_with(name), "the error does not name the file: {m}");
        }
    }
});
