//! Hostile files against the loaders: each class of fault (a panic in a dependency, a memory
//! bomb, a read outside the scene's folder, camera values an f32 cannot hold) gets a small
//! file written here and a typed error back. The bombs run in a child process whose address
//! space is capped far below what the file asks for, so an allocation made from the file's
//! word fails the test instead of passing quietly on a large machine.

use std::path::Path;
use std::time::Duration;

use golden_tests::child::in_child;
use golden_tests::hostile;
use scene_core::budget::{Budget, Limit};
use scene_core::gltf_io::{self, ExternalFiles, ImportOptions};
use scene_core::{GltfError, Image, ImageError, builtin};

/// Address space of the bomb tests' children: the test binary, its threads and the small
/// files fit; any of the bombs' allocations (gigabytes) does not.
const CAP: u64 = 1 << 30;
const TIMEOUT: Duration = Duration::from_secs(120);

fn budget_error(e: &GltfError) -> &scene_core::BudgetError {
    match e {
        GltfError::Budget(b) => b,
        other => panic!("expected a budget error, got {other}"),
    }
}

#[test]
fn camera_type_without_its_projection_is_an_error_not_a_panic() {
    let e =
        gltf_io::import_slice(&hostile::camera_type_mismatch(), Path::new("cam.gltf")).unwrap_err();
    assert!(matches!(e, GltfError::Read { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("cam.gltf") && text.contains("camera 0") && text.contains("orthographic"),
        "{text}"
    );
    // The other way round too: a perspective type with only an orthographic object.
    let mut v = hostile::cornell_json();
    let persp = v["cameras"][0]["perspective"].take();
    v["cameras"][0]
        .as_object_mut()
        .unwrap()
        .remove("perspective");
    v["cameras"][0]["orthographic"] =
        serde_json::json!({"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": persp["zfar"]});
    let e = gltf_io::import_slice(&hostile::to_bytes(&v), Path::new("cam2.gltf")).unwrap_err();
    assert!(e.to_string().contains("no perspective object"), "{e}");
}

#[test]
fn exr_bomb_is_refused_before_allocating() {
    let run = in_child(
        "exr_bomb_is_refused_before_allocating",
        CAP,
        TIMEOUT,
        || {
            // 100 000 x 100 000 pixels: 120 GB as linear RGB, from a file of about 700 bytes.
            let bytes = hostile::exr_bomb(100_000, 100_000);
            assert!(bytes.len() < 2000, "{} bytes", bytes.len());
            let e =
                Image::decode_exr(&bytes, Path::new("bomb.exr"), &Budget::default()).unwrap_err();
            let ImageError::Budget(b) = &e else {
                panic!("expected a budget error, got {e}")
            };
            assert_eq!(b.which, Limit::ImageBytes);
            assert_eq!(b.needed, 100_000u64 * 100_000 * 12);
            assert_eq!(b.limit, Budget::default().image_bytes);
            assert!(e.to_string().contains("bomb.exr"), "{e}");
            // Through a file, as imalyzer and the harness read them.
            let dir = hostile::scratch_dir("exr-bomb");
            let p = hostile::write(&dir, "bomb.exr", &bytes);
            assert!(matches!(Image::read(&p), Err(ImageError::Budget(_))));
            // A window whose size overflows i32 arithmetic (max < min) is an error too.
            let e = Image::decode_exr(
                &hostile::exr_bomb(i32::MIN + 2, 3),
                Path::new("neg.exr"),
                &Budget::default(),
            );
            assert!(e.is_err());
            std::fs::remove_dir_all(&dir).ok();
        },
    );
    if let Some(run) = run {
        eprintln!("EXR bomb refused in a child within {:?}", run.elapsed);
    }
}

#[test]
fn a_panic_in_the_exr_decoder_is_an_error_not_an_abort() {
    let bytes = hostile::exr_b44_overflow();
    // Before: decoded on rayon's threads, this aborted the process (exit 134) in any build
    // with overflow checks, tests included.
    let r = Image::decode_exr(&bytes, Path::new("b44.exr"), &Budget::default());
    if cfg!(debug_assertions) {
        match r {
            Err(ImageError::DecoderFault { path, message }) => {
                assert!(path.ends_with("b44.exr"));
                assert!(message.contains("overflow"), "{message}");
            }
            other => panic!("expected a caught decoder fault, got {other:?}"),
        }
    } else {
        // Release builds wrap instead of panicking: any outcome but a panic is fine.
        let _ = r;
    }
}

#[test]
fn png_bomb_is_refused_before_allocating() {
    in_child(
        "png_bomb_is_refused_before_allocating",
        CAP,
        TIMEOUT,
        || {
            // 66 KB of 1-bit PNG for 16384 x 16384 pixels (3 GiB as f32 RGB).
            let bytes = hostile::png_bomb(16384);
            assert!(bytes.len() < 100_000, "{} bytes", bytes.len());
            let e =
                Image::decode_png(&bytes, Path::new("bomb.png"), &Budget::default()).unwrap_err();
            let ImageError::Budget(b) = &e else {
                panic!("expected a budget error, got {e}")
            };
            assert_eq!(b.which, Limit::ImageBytes);
            // One byte a pixel decoded (grey) plus 12 for the linear copy.
            assert_eq!(b.needed, 16384u64 * 16384 * 13);
            // A budget that admits it is the caller's choice: a smaller bomb loads.
            let ok = Image::decode_png(
                &hostile::png_bomb(512),
                Path::new("ok.png"),
                &Budget::default(),
            )
            .unwrap();
            assert_eq!((ok.width, ok.height), (512, 512));
            assert!(ok.pixels.iter().all(|p| *p == scene_core::glam::Vec3::ZERO));
        },
    );
}

#[test]
fn gltf_sparse_instancing_bomb_is_refused_before_allocating() {
    in_child(
        "gltf_sparse_instancing_bomb_is_refused_before_allocating",
        CAP,
        TIMEOUT,
        || {
            // 2^26 vertices from a sparse-only accessor, instanced by 4 nodes.
            let bytes = hostile::sparse_instanced(1 << 26, 4);
            assert!(bytes.len() < 1000, "{} bytes", bytes.len());
            let e = gltf_io::import_slice(&bytes, Path::new("sparse.gltf")).unwrap_err();
            let b = budget_error(&e);
            assert_eq!(b.which, Limit::Vertices, "{e}");
            assert_eq!(b.needed, 1 << 26);
            // Instancing is counted: with a budget that admits one instance, the second fails.
            let options = ImportOptions {
                budget: Budget {
                    vertices: 1 << 16,
                    ..Budget::default()
                },
                ..Default::default()
            };
            let e = gltf_io::import_slice_with(
                &hostile::sparse_instanced(40_000, 4),
                Path::new("sparse.gltf"),
                &options,
            )
            .unwrap_err();
            let b = budget_error(&e);
            assert_eq!((b.which, b.needed), (Limit::Vertices, 80_000), "{e}");
            // A small instanced sparse mesh imports (every vertex zero but one: validation
            // drops the degenerate triangles and says so).
            let r = gltf_io::import_slice(&hostile::sparse_instanced(6, 2), Path::new("s.gltf"));
            assert!(
                r.is_ok() || matches!(r, Err(GltfError::Invalid { .. })),
                "{r:?}"
            );
        },
    );
}

#[test]
fn gltf_texture_bomb_is_refused_before_decoding() {
    in_child(
        "gltf_texture_bomb_is_refused_before_decoding",
        CAP,
        TIMEOUT,
        || {
            let bytes = hostile::triangle_with_texture(&hostile::png_bomb(16384));
            let e = gltf_io::import_slice(&bytes, Path::new("texture.gltf")).unwrap_err();
            let b = budget_error(&e);
            assert_eq!(b.which, Limit::ImageBytes, "{e}");
            assert!(e.to_string().contains("texture 0"), "{e}");
            // The scene's total counts textures too.
            let options = ImportOptions {
                budget: Budget {
                    scene_bytes: 1 << 20,
                    ..Budget::default()
                },
                ..Default::default()
            };
            let bytes = hostile::triangle_with_texture(&hostile::png_bomb(512));
            let e = gltf_io::import_slice_with(&bytes, Path::new("t.gltf"), &options).unwrap_err();
            assert_eq!(budget_error(&e).which, Limit::SceneBytes, "{e}");
            assert!(gltf_io::import_slice(&bytes, Path::new("t.gltf")).is_ok());
        },
    );
}

/// A scene folder `dir/scene` holding `buf.bin`, with `dir/outside.bin` beside it.
fn scene_folder() -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = hostile::scratch_dir("uri");
    let scene = dir.join("scene");
    std::fs::create_dir_all(scene.join("sub")).unwrap();
    std::fs::write(scene.join("buf.bin"), hostile::triangle_buffer()).unwrap();
    std::fs::write(
        scene.join("sub").join("buf.bin"),
        hostile::triangle_buffer(),
    )
    .unwrap();
    std::fs::write(dir.join("outside.bin"), hostile::triangle_buffer()).unwrap();
    (dir, scene)
}

fn import_uri(scene: &Path, uri: &str, policy: ExternalFiles) -> Result<(), GltfError> {
    let path = hostile::write(scene, "t.gltf", &hostile::triangle_with_buffer_uri(uri));
    let options = ImportOptions {
        external_files: policy,
        ..Default::default()
    };
    gltf_io::import_with(&path, &options).map(|_| ())
}

#[test]
fn uris_resolve_only_inside_the_scene_folder() {
    let (dir, scene) = scene_folder();
    let outside = dir.join("outside.bin");
    // Inside: plain, in a subfolder, percent-encoded, file: relative.
    for ok in [
        "buf.bin",
        "sub/buf.bin",
        "sub/../buf.bin",
        "b%75f.bin",
        "file:buf.bin",
    ] {
        import_uri(&scene, ok, ExternalFiles::SceneFolder).unwrap_or_else(|e| panic!("{ok}: {e}"));
    }
    // Absolute paths and file: URIs that lie inside the folder are read too.
    let inside = scene.join("buf.bin").canonicalize().unwrap();
    import_uri(
        &scene,
        &format!("file://{}", inside.display()),
        ExternalFiles::SceneFolder,
    )
    .unwrap();
    import_uri(
        &scene,
        &inside.display().to_string(),
        ExternalFiles::SceneFolder,
    )
    .unwrap();
    let refused = [
        "file:///etc/passwd".to_string(),
        "file:///dev/zero".to_string(),
        "/etc/passwd".to_string(),
        "/dev/zero".to_string(),
        "../outside.bin".to_string(),
        "sub/../../outside.bin".to_string(),
        outside.display().to_string(),
        format!("file://{}", outside.display()),
        "http://example.invalid/buf.bin".to_string(),
        "%2e%2e/outside.bin".to_string(),
        // Refused before anything outside is looked at: a missing file out there gives the
        // same error as a present one.
        "../no-such-file.bin".to_string(),
        "../../../../../../../../no/such/dir/x.bin".to_string(),
    ];
    for uri in &refused {
        match import_uri(&scene, uri, ExternalFiles::SceneFolder) {
            Err(GltfError::RefusedUri {
                uri: named, path, ..
            }) => {
                assert_eq!(&named, uri);
                assert!(path.ends_with("t.gltf"));
            }
            other => panic!("{uri}: expected RefusedUri, got {other:?}"),
        }
    }
    // A symbolic link inside the folder that points outside it.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&outside, scene.join("link.bin")).unwrap();
        let e = import_uri(&scene, "link.bin", ExternalFiles::SceneFolder).unwrap_err();
        assert!(matches!(e, GltfError::RefusedUri { .. }), "{e}");
        import_uri(&scene, "link.bin", ExternalFiles::Anywhere).unwrap();
    }
    // The caller may allow files elsewhere; devices stay refused whatever the policy.
    import_uri(&scene, "../outside.bin", ExternalFiles::Anywhere).unwrap();
    import_uri(
        &scene,
        &outside.display().to_string(),
        ExternalFiles::Anywhere,
    )
    .unwrap();
    for device in ["file:///dev/zero", "/dev/zero"] {
        let e = import_uri(&scene, device, ExternalFiles::Anywhere).unwrap_err();
        assert!(matches!(e, GltfError::RefusedUri { .. }), "{device}: {e}");
    }
    // Or refuse every external file.
    let e = import_uri(&scene, "buf.bin", ExternalFiles::Refuse).unwrap_err();
    assert!(matches!(e, GltfError::RefusedUri { .. }), "{e}");
    // From memory, no external file is read.
    let e = gltf_io::import_slice(
        &hostile::triangle_with_buffer_uri("buf.bin"),
        Path::new("mem.gltf"),
    )
    .unwrap_err();
    assert!(matches!(e, GltfError::RefusedUri { .. }), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sparse_attributes_strips_and_huge_png_headers_are_charged_before_reading() {
    in_child(
        "sparse_attributes_strips_and_huge_png_headers_are_charged_before_reading",
        CAP,
        TIMEOUT,
        || {
            // A NORMAL accessor of 2^40 sparse-only values beside 3 positions.
            let e = gltf_io::import_slice(&hostile::sparse_normals(1 << 40), Path::new("n.gltf"))
                .unwrap_err();
            assert!(
                e.to_string()
                    .contains("NORMAL accessor 1 has 1099511627776 values for 3"),
                "{e}"
            );
            // A strip of k vertices makes k - 2 triangles: 3 (k - 2) indices are charged.
            let mut v: serde_json::Value =
                serde_json::from_slice(&hostile::sparse_instanced(1000, 1)).unwrap();
            v["meshes"][0]["primitives"][0]["mode"] = serde_json::json!(5);
            let options = ImportOptions {
                budget: Budget {
                    indices: 2000,
                    ..Budget::default()
                },
                ..Default::default()
            };
            let e =
                gltf_io::import_slice_with(&hostile::to_bytes(&v), Path::new("s.gltf"), &options)
                    .unwrap_err();
            let b = budget_error(&e);
            assert_eq!((b.which, b.needed), (Limit::Indices, 3 * 998), "{e}");
            // A texture whose PNG header declares 100 000 x 100 000 pixels: the budget
            // refuses it from the header.
            let png = hostile::png_header_only(100_000, 100_000);
            let e =
                gltf_io::import_slice(&hostile::triangle_with_texture(&png), Path::new("t.gltf"))
                    .unwrap_err();
            let b = budget_error(&e);
            assert_eq!(
                (b.which, b.needed),
                (Limit::ImageBytes, 100_000u64 * 100_000 * 12),
                "{e}"
            );
            let e = Image::decode_png(&png, Path::new("h.png"), &Budget::default()).unwrap_err();
            assert!(matches!(e, ImageError::Budget(_)), "{e}");
            // 1.3e9 x 1.3e9 (w h 12 overflows u64 arithmetic that does not saturate): one row
            // alone is over the decoder's header-stage limit, which refuses it first.
            let png = hostile::png_header_only(1_300_000_000, 1_300_000_000);
            let e =
                gltf_io::import_slice(&hostile::triangle_with_texture(&png), Path::new("t.gltf"))
                    .unwrap_err();
            assert!(
                e.to_string().contains("texture 0") && e.to_string().contains("limit"),
                "{e}"
            );
        },
    );
}

#[test]
fn fifos_are_refused_without_blocking() {
    let dir = hostile::scratch_dir("fifo");
    let fifo = dir.join("f.json");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("mkfifo is not available here; not tested");
        return;
    }
    let scene = builtin::scene("cornell").unwrap();
    // Each of these would block forever opening the FIFO for reading.
    let e = bench_harness::load_camera_list(&fifo, &scene).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let gltf = dir.join("f.gltf");
    std::process::Command::new("mkfifo")
        .arg(&gltf)
        .status()
        .unwrap();
    let e = gltf_io::import(&gltf).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let exr = dir.join("f.exr");
    std::process::Command::new("mkfifo")
        .arg(&exr)
        .status()
        .unwrap();
    let e = Image::read(&exr).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_external_buffer_over_the_budget_is_refused_before_reading() {
    let (dir, scene) = scene_folder();
    let big = scene.join("big.bin");
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(64 << 20).unwrap(); // sparse: no disk used
    let path = hostile::write(
        &scene,
        "t.gltf",
        &hostile::triangle_with_buffer_uri("big.bin"),
    );
    let options = ImportOptions {
        budget: Budget {
            scene_bytes: 16 << 20,
            ..Budget::default()
        },
        ..Default::default()
    };
    let e = gltf_io::import_with(&path, &options).unwrap_err();
    let b = budget_error(&e);
    // The buffer, with the glTF file already charged (a few kilobytes).
    assert_eq!(b.which, Limit::SceneBytes, "{e}");
    assert!(
        b.needed > 64 << 20 && b.needed < (64 << 20) + (64 << 10),
        "{e}"
    );
    assert!(e.to_string().contains("big.bin"), "{e}");
    assert!(gltf_io::import_with(&path, &ImportOptions::default()).is_ok());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn budgets_are_configurable_and_defaults_admit_the_builtin_scenes() {
    for name in ["cornell", "primitives", "corridor"] {
        let bytes = hostile::exported(name, "glb");
        gltf_io::import_slice(&bytes, Path::new("b.glb")).unwrap();
        let tight = ImportOptions {
            budget: Budget {
                indices: 30,
                ..Budget::default()
            },
            ..Default::default()
        };
        let e = gltf_io::import_slice_with(&bytes, Path::new("b.glb"), &tight).unwrap_err();
        assert_eq!(budget_error(&e).which, Limit::Indices, "{e}");
    }
    // A file larger than the file budget is refused before it is read.
    let dir = hostile::scratch_dir("file-budget");
    let p = hostile::write(&dir, "c.glb", &hostile::exported("cornell", "glb"));
    let options = ImportOptions {
        budget: Budget {
            file_bytes: 100,
            ..Budget::default()
        },
        ..Default::default()
    };
    let e = gltf_io::import_with(&p, &options).unwrap_err();
    assert_eq!(budget_error(&e).which, Limit::FileBytes, "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn camera_lists_go_through_the_scene_camera_check() {
    let scene = builtin::scene("cornell").unwrap();
    let lists = hostile::bad_camera_lists();
    // An up hint that is zero, huge or parallel to the view is a camera: its view takes
    // another up (`Camera::view_up`) and is finite.
    for up in ["[0, 0, 0]", "[3e38, 3e38, 0]", "[0, 0, 1]"] {
        let text = lists[0]
            .1
            .replace(", \"far\": 1e39", &format!(", \"up\": {up}"));
        let cams = bench_harness::parse_camera_list(&text, &scene, "cams.json").unwrap();
        let v = scene_core::View::from_camera(&cams[0]);
        assert!(
            v.up.is_finite() && v.forward.is_finite() && v.up.dot(v.forward).abs() < 1e-5,
            "up {up}: {v:?}"
        );
    }
    for (what, text) in lists {
        let e = bench_harness::parse_camera_list(&text, &scene, "cams.json").expect_err(what);
        let msg = e.to_string();
        assert!(
            msg.contains("cams.json") && msg.contains("view0"),
            "{what}: {msg}"
        );
    }
}

#[test]
fn every_seed_of_every_fuzz_target_loads_or_is_refused_without_a_panic() {
    use golden_tests::fuzz::{self, Context, Outcome};
    let dir = hostile::scratch_dir("seeds");
    let ctx = Context::new(fuzz::fuzz_budget(), &dir);
    let mut loaded = 0;
    for t in fuzz::targets() {
        for (i, seed) in (t.seeds)().iter().enumerate() {
            match fuzz::run(&t, seed, &ctx) {
                Outcome::Panicked(m) => panic!("{} seed {i}: {m}", t.name),
                Outcome::Ok => loaded += 1,
                Outcome::Refused(_) => {}
            }
        }
    }
    // Most seeds are good files (the mutations start from them).
    assert!(loaded >= 20, "{loaded} seeds loaded");
    std::fs::remove_dir_all(&dir).ok();
}
