//! The view-sample pass (raster + resolve, lavapipe, validation on) against
//! the CPU oracle's primary view samples, and one exact case.

use alias_free_shadows::gpu::shared::{GpuTriangle, GpuViewSample, VIEW_SAMPLE_VALID};
use alias_free_shadows::gpu::view_samples::{read_view_samples, ViewSamplePass};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::scene::{file, Camera, SceneTriangle};
use alias_free_shadows::vulkan::{ContextOptions, GpuContext};
use glam::{DVec3, Vec3};

/// Camera-relative f32 triangles, ids = scene order.
fn gpu_triangles(tris: &[SceneTriangle], eye: DVec3) -> Vec<GpuTriangle> {
    tris.iter()
        .map(|t| GpuTriangle::new(t.vertices.map(|v| (v - eye).as_vec3()), 0, t.mesh))
        .collect()
}

fn render(ctx: &GpuContext, camera: &Camera, tris: &[GpuTriangle]) -> (Vec<GpuViewSample>, f64) {
    let mut pass = ViewSamplePass::new(ctx).unwrap();
    let (buf, ms) = pass.render(ctx, camera, tris, None).unwrap();
    let n = camera.width as usize * camera.height as usize;
    (read_view_samples(ctx, buf, n).unwrap(), ms)
}

fn compare_with_oracle(spec: &str, width: u32, height: u32) {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut desc = file::load(spec).unwrap();
    desc.camera.width = width;
    desc.camera.height = height;
    let camera = desc.camera;
    let tris = desc.scene.triangles();
    let oracle = Oracle::new(&tris, camera.eye).primary_view_samples(&camera);
    let gtris = gpu_triangles(&tris, camera.eye);
    let (gpu, ms) = render(&ctx, &camera, &gtris);
    // The normal the pass can reach: that of the f32 camera-relative
    // triangle it is given, computed in f64. On thin triangles (hairball)
    // it differs from the oracle's (f64 world vertices) by up to ~2e-5.
    let input_normal = |id: u32| {
        let t = gtris[id as usize];
        let v = [t.v0, t.v1, t.v2].map(|v| Vec3::from_array(v).as_dvec3());
        (v[1] - v[0]).cross(v[2] - v[0]).normalize()
    };
    let (mut input_bad, mut worst_input) = (0usize, 0f64);
    assert_eq!(gpu.len(), oracle.samples.len());

    let pixels = gpu.len();
    let (mut coverage_diff, mut both, mut same_id) = (0usize, 0usize, 0usize);
    let (mut position_bad, mut normal_bad) = (0usize, 0usize);
    let (mut worst_position, mut worst_normal) = (0f64, 0f64);
    for (i, (g, o)) in gpu.iter().zip(&oracle.samples).enumerate() {
        let valid = g.flags & VIEW_SAMPLE_VALID != 0;
        if !valid {
            assert_eq!(
                *g,
                GpuViewSample::default(),
                "pixel {i}: invalid but not zero"
            );
        }
        match (valid, o) {
            (true, Some(o)) => {
                both += 1;
                if g.triangle != o.triangle {
                    continue;
                }
                same_id += 1;
                let expected = o.position - camera.eye;
                let got = Vec3::from_array(g.position).as_dvec3();
                let rel = (got - expected).length() / expected.length();
                worst_position = worst_position.max(rel);
                if rel > 1e-4 {
                    position_bad += 1;
                }
                let normal = Vec3::from_array(g.normal).as_dvec3();
                let dn = (normal - o.normal).length();
                worst_normal = worst_normal.max(dn);
                if dn > 1e-4 {
                    normal_bad += 1;
                }
                let mut n = input_normal(g.triangle);
                if n.dot(o.normal) < 0.0 {
                    n = -n;
                }
                let di = (normal - n).length();
                worst_input = worst_input.max(di);
                if di > 1e-5 {
                    input_bad += 1;
                }
            }
            (false, None) => {}
            _ => coverage_diff += 1,
        }
    }
    println!(
        "{spec} {width}x{height}: {ms:.2} GPU ms; coverage differs on {coverage_diff}/{pixels}; \
         same id on {same_id}/{both} seen by both; position > 1e-4 relative on {position_bad} \
         (worst {worst_position:.2e}); normal vs oracle > 1e-4 on {normal_bad} (worst \
         {worst_normal:.2e}), vs the f32 input triangle's > 1e-5 on {input_bad} (worst \
         {worst_input:.2e})"
    );
    assert!(both > 0, "{spec}: nothing seen");
    assert!(
        coverage_diff as f64 <= 0.005 * pixels as f64,
        "{spec}: coverage differs on {coverage_diff} of {pixels} pixels"
    );
    assert!(
        same_id as f64 >= 0.99 * both as f64,
        "{spec}: same triangle on only {same_id} of {both} pixels"
    );
    assert_eq!(position_bad, 0, "{spec}: positions off");
    assert_eq!(normal_bad, 0, "{spec}: normals off");
    assert_eq!(input_bad, 0, "{spec}: normals off the input triangles'");
    ctx.check_validation().unwrap();
}

#[test]
fn demo_matches_oracle() {
    compare_with_oracle("builtin:demo", 128, 96);
}

#[test]
fn hairball_matches_oracle() {
    compare_with_oracle("builtin:hairball", 128, 96);
}

#[test]
fn columns_matches_oracle() {
    compare_with_oracle("builtin:columns", 128, 96);
}

/// A camera 5 units in front of a 20×20 quad (two triangles split along
/// y = x): every pixel sees it, on the right triangle, on its plane.
#[test]
fn quad_fills_the_view_exactly() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let eye = DVec3::new(0.3, -0.2, 5.0);
    let camera = Camera {
        eye,
        target: DVec3::new(0.3, -0.2, 0.0),
        up: DVec3::Y,
        fov_y_deg: 60.0,
        width: 64,
        height: 48,
    };
    let quad = [
        [
            DVec3::new(-10.0, -10.0, 0.0),
            DVec3::new(10.0, -10.0, 0.0),
            DVec3::new(10.0, 10.0, 0.0),
        ],
        [
            DVec3::new(-10.0, -10.0, 0.0),
            DVec3::new(10.0, 10.0, 0.0),
            DVec3::new(-10.0, 10.0, 0.0),
        ],
    ];
    let tris: Vec<GpuTriangle> = quad
        .iter()
        .map(|v| GpuTriangle::new(v.map(|p| (p - eye).as_vec3()), 0, 0))
        .collect();
    let (gpu, _) = render(&ctx, &camera, &tris);
    let mut checked = 0;
    for y in 0..camera.height {
        for x in 0..camera.width {
            let s = gpu[(y * camera.width + x) as usize];
            assert_eq!(s.flags, VIEW_SAMPLE_VALID, "pixel ({x}, {y}) not seen");
            let d = camera.ray_direction(x, y);
            let hit = eye + d * (eye.z / -d.z);
            let p = Vec3::from_array(s.position).as_dvec3();
            assert!(
                (p - (hit - eye)).length() <= 1e-5 * 5.0,
                "pixel ({x}, {y}): {p:?} vs {:?}",
                hit - eye
            );
            assert!(
                (p.z + 5.0).abs() <= 1e-5,
                "pixel ({x}, {y}) off the plane: {p:?}"
            );
            assert_eq!(s.normal, [0.0, 0.0, 1.0], "pixel ({x}, {y}) normal");
            // Triangle 0 holds y < x, triangle 1 y > x; skip the diagonal.
            if (hit.x - hit.y).abs() > 1e-3 {
                let expected = if hit.y < hit.x { 0 } else { 1 };
                assert_eq!(s.triangle, expected, "pixel ({x}, {y}) triangle");
                checked += 1;
            }
        }
    }
    assert!(checked > 3000);
    ctx.check_validation().unwrap();
}

/// No triangles: every sample is zero.
#[test]
fn empty_scene_is_all_zero() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let camera = Camera {
        eye: DVec3::ZERO,
        target: DVec3::NEG_Z,
        up: DVec3::Y,
        fov_y_deg: 45.0,
        width: 13,
        height: 7,
    };
    let (gpu, _) = render(&ctx, &camera, &[]);
    assert!(gpu.iter().all(|s| *s == GpuViewSample::default()));
    ctx.check_validation().unwrap();
}

/// GPU time at 512²: `cargo test --release --test view_samples -- --ignored --nocapture`.
#[test]
#[ignore]
fn timing_512() {
    let ctx = GpuContext::new(&ContextOptions::default()).unwrap();
    for spec in ["builtin:demo", "builtin:torus_knot:100000"] {
        let mut desc = file::load(spec).unwrap();
        desc.camera.width = 512;
        desc.camera.height = 512;
        let tris = gpu_triangles(&desc.scene.triangles(), desc.camera.eye);
        let mut pass = ViewSamplePass::new(&ctx).unwrap();
        let mut times = Vec::new();
        for _ in 0..5 {
            let (_, ms) = pass.render(&ctx, &desc.camera, &tris, None).unwrap();
            times.push(ms);
        }
        println!(
            "{spec} 512x512, {} triangles: GPU ms {times:.2?}",
            tris.len()
        );
    }
}

/// The raster's cull (the triangles whose image holds no pixel centre are
/// left out of the draw) changes no view sample: with and without it the
/// samples are the same bytes, on built-in scenes at odd sizes and on
/// tiny triangles with an edge a few thousandths of a pixel on either side
/// of a pixel centre (at depths from 0.5 to 400, so their f32 corners
/// round differently), slivers between the centres, and large triangles
/// reaching behind the eye. The cull must also leave some out here.
#[test]
fn cull_leaves_the_view_samples_unchanged() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut pass = ViewSamplePass::new(&ctx).unwrap();
    let mut both = |camera: &Camera, tris: &[GpuTriangle], what: &str| {
        let n = camera.width as usize * camera.height as usize;
        let mut out = Vec::new();
        for cull in [false, true] {
            pass.set_cull(cull);
            let (buf, _) = pass.render(&ctx, camera, tris, None).unwrap();
            out.push((
                read_view_samples(&ctx, buf, n).unwrap(),
                pass.drawn_triangles(),
            ));
        }
        assert_eq!(out[0].1, tris.len(), "{what}: all drawn without the cull");
        for (i, (a, b)) in out[0].0.iter().zip(&out[1].0).enumerate() {
            assert_eq!(a, b, "{what}: pixel {i} differs with the cull");
        }
        out[1].1
    };
    let mut culled_somewhere = false;
    for (spec, w, h) in [
        ("builtin:torus_knot:20000", 61, 47),
        ("builtin:hairball", 33, 80),
        ("builtin:demo", 97, 100),
    ] {
        let mut desc = file::load(spec).unwrap();
        desc.camera.width = w;
        desc.camera.height = h;
        let tris = gpu_triangles(&desc.scene.triangles(), desc.camera.eye);
        let drawn = both(&desc.camera, &tris, spec);
        culled_somewhere |= drawn < tris.len();
    }

    // A camera at the origin looking down -z; `at(px, py, depth)` is the
    // camera-relative point whose image is (px, py) in pixels.
    let camera = Camera {
        eye: DVec3::ZERO,
        target: DVec3::new(0.1, -0.05, -1.0),
        up: DVec3::Y,
        fov_y_deg: 50.0,
        width: 31,
        height: 23,
    };
    let (r, u, f) = camera.basis();
    let tan = (camera.fov_y_deg.to_radians() * 0.5).tan();
    let aspect = camera.width as f64 / camera.height as f64;
    let at = |px: f64, py: f64, depth: f64| {
        let nx = 2.0 * px / camera.width as f64 - 1.0;
        let ny = 2.0 * py / camera.height as f64 - 1.0;
        (f + r * (nx * tan * aspect) - u * (ny * tan)) * depth
    };
    let offsets = [0.0005, 0.001, 0.002, 0.004, 0.01, 0.03];
    let mut tris = Vec::new();
    for j in 0..camera.height {
        for i in 0..camera.width {
            let (cx, cy) = (i as f64 + 0.5, j as f64 + 0.5);
            let k = (i + 7 * j) as usize;
            let d = offsets[k % offsets.len()] * if k.is_multiple_of(2) { 1.0 } else { -1.0 };
            let depth = 0.5 * 1.9f64.powi((k % 10) as i32);
            // A vertical edge at cx + d (the centre outside when d > 0),
            // the triangle to its right; in turn a horizontal edge.
            let v = if (k / 2).is_multiple_of(2) {
                [
                    at(cx + d, cy - 0.3, depth),
                    at(cx + d, cy + 0.3, depth),
                    at(cx + 0.35, cy, depth),
                ]
            } else {
                [
                    at(cx - 0.3, cy + d, depth),
                    at(cx + 0.3, cy + d, depth),
                    at(cx, cy + 0.35, depth),
                ]
            };
            tris.push(GpuTriangle::new(v.map(|p| p.as_vec3()), 0, 0));
        }
    }
    // Slivers along rows and columns halfway between the centres.
    for j in 0..camera.height {
        let y = j as f64 + 0.02;
        tris.push(GpuTriangle::new(
            [
                at(0.3, y, 3.0),
                at(30.7, y + 0.01, 3.0),
                at(30.7, y - 0.01, 3.0),
            ]
            .map(|p| p.as_vec3()),
            0,
            0,
        ));
    }
    // Large triangles behind the others, one corner behind the eye.
    for (a, b) in [(-1.0, 2.0), (1.0, -3.0)] {
        let v = [
            DVec3::new(a, b, 1.0),
            at(0.0, 0.0, 500.0) + DVec3::new(a, 0.0, 0.0),
            at(31.0, 23.0, 600.0),
        ];
        tris.push(GpuTriangle::new(v.map(|p| p.as_vec3()), 0, 0));
    }
    let drawn = both(&camera, &tris, "edges near pixel centres");
    culled_somewhere |= drawn < tris.len();
    // The test means something only if the cull left triangles out.
    assert!(culled_somewhere, "the cull left nothing out");
    ctx.check_validation().unwrap();
}

#[test]
fn bands_leave_the_view_samples_unchanged() {
    // An image whose samples pass one storage binding is resolved in bands
    // of rows (multiples of 64, each dispatch binding its rows' ranges);
    // forced bands give every pixel the sample of a single dispatch,
    // including a last band of 8 rows and a width that is no multiple of
    // the workgroup's 8.
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut desc = file::load("builtin:demo").unwrap();
    desc.camera.width = 45;
    desc.camera.height = 200;
    let camera = desc.camera;
    let tris = gpu_triangles(&desc.scene.triangles(), camera.eye);
    let n = camera.width as usize * camera.height as usize;
    let mut pass = ViewSamplePass::new(&ctx).unwrap();
    let whole = {
        let (buf, _) = pass.render(&ctx, &camera, &tris, None).unwrap();
        read_view_samples(&ctx, buf, n).unwrap()
    };
    assert!(whole.iter().any(|s| s.flags & VIEW_SAMPLE_VALID != 0));
    // 64 rows, and 100 rounded down to 64: bands of 64, 64, 64, 8.
    for limit in [64, 100, 128] {
        pass.set_band_limit(Some(limit));
        let (buf, _) = pass.render(&ctx, &camera, &tris, None).unwrap();
        let banded = read_view_samples(&ctx, buf, n).unwrap();
        for (i, (a, b)) in whole.iter().zip(&banded).enumerate() {
            assert_eq!(a, b, "bands of {limit} rows: pixel {i} differs");
        }
    }
    // Fewer rows than one band's multiple: an error, not a panic or an
    // empty image.
    pass.set_band_limit(Some(63));
    let err = pass.render(&ctx, &camera, &tris, None).err();
    assert!(
        err.as_ref()
            .is_some_and(|e| e.to_string().contains("multiples of 64 rows")),
        "{err:?}"
    );
    ctx.check_validation().unwrap();
}
