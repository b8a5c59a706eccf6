//! `dmu render --stereo --shared-far-px` and `--reproject`: the cheaper
//! pairs against the same pair drawn in full, with asymmetric eye fields of
//! view.
//! Included from `tests.rs`.

use serde_json::Value;

use super::{path, render};

/// `dmu render --stereo` inside the 200k plant, looking down the pipe rack
/// (millimetres, 320x320 headset-like eyes, two frames) with `variant`'s
/// flags: the JSON report and the folder of its images.
fn pair(variant: &[&str]) -> (Value, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let png = path(dir.path(), "s.png");
    let mut args = vec![
        "--plant-triangles",
        "200k",
        "--eye",
        "4509000,5349750,13700",
        "--target",
        "4572000,5351750,14000",
        "--size",
        "320x320",
        "--stereo",
        "--ipd",
        "65",
        "--eye-fov=-52,43,-50,48",
        "--frames",
        "2",
        "--json",
        "-o",
        &png,
    ];
    args.extend_from_slice(variant);
    let out = render(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (serde_json::from_slice(&out.stdout).unwrap(), dir)
}

#[test]
fn shared_far_pair_matches_the_full_pair_within_its_bound() {
    dmu_testkit::with_gpu(|_| {
        let (v, dir) = pair(&["--shared-far-px", "0.5"]);
        let f = &v["stereo"]["shared_far"];
        assert!(
            f["disparity_error_bound_px"].as_f64().unwrap() <= 0.5 + 1e-9,
            "{f:#}"
        );
        // The split: where 65 mm of eye separation is what may be shared.
        let split = f["split_depth"].as_f64().unwrap();
        let fx = f["pixels_per_tangent"].as_f64().unwrap();
        // fx from the field of view: 320 px over tan 52° + tan 43°.
        let expected_fx = 320.0 / (52f64.to_radians().tan() + 43f64.to_radians().tan());
        assert!((fx - expected_fx).abs() < 1e-6, "{fx} vs {expected_fx}");
        assert!(split > 65.0 * fx, "{split}");
        // Both parts are drawn, and the composite differs from the full pair
        // only on a few pixels (triangles crossing the split, sub-pixel shifts).
        let triangles = &f["triangles"];
        assert!(triangles["far"].as_u64().unwrap() > 0, "{f:#}");
        assert!(triangles["near_both_eyes"].as_u64().unwrap() > 0, "{f:#}");
        for e in 0..2 {
            let frac = f["image_difference"]["fraction_differing"][e]
                .as_f64()
                .unwrap();
            assert!(frac < 0.01, "eye {e}: {frac} of pixels differ");
        }
        for name in ["s-shared-left.png", "s-shared-right.png"] {
            let image = image::open(dir.path().join(name)).expect(name).to_rgba8();
            assert_eq!(image.dimensions(), (320, 320));
        }
        // A mirrored pair of eye fields of view is reported as given.
        assert_eq!(f["eye_fov_deg"][1][0].as_f64().map(f64::round), Some(-43.0));
    });
}

/// `--reproject`: the right eye moved from the wide left eye by depth, beside
/// the pair in full (both lit from between the eyes): the left eye is the
/// full pair's, the right differs along edges and gaps only, and the report
/// gives the gaps, the parts' times and the ratios.
#[test]
fn reprojected_pair_matches_the_full_pair_but_along_edges_and_gaps() {
    dmu_testkit::with_gpu(|_| {
        let (v, dir) = pair(&["--reproject"]);
        assert!(v["stereo"]["shared_far"].is_null());
        let r = &v["stereo"]["reprojected"];
        // The left window, the right eye's (mirrored: 52 - 43 degrees further
        // right) and the margin, on the left eye's pixel grid.
        let fx = 320.0 / (52f64.to_radians().tan() + 43f64.to_radians().tan());
        let union = (2.0 * 52f64.to_radians().tan() * fx).ceil();
        // The margin: a fortieth of the eye's width.
        assert_eq!(r["wide_width"].as_f64(), Some(union + 8.0), "{r:#}");
        let gaps = r["gap_fraction"].as_f64().unwrap();
        assert!(gaps > 0.0 && gaps < 0.1, "{r:#}");
        let over = &r["image_difference"]["fraction_over_8_levels"];
        assert!(over[0].as_f64().unwrap() < 0.001, "{r:#}");
        assert!(over[1].as_f64().unwrap() < 0.1, "{r:#}");
        for key in ["ratio", "true_stereo_ratio", "wide_pass_ms", "reproject_ms"] {
            assert!(r[key].as_f64().unwrap() > 0.0, "{key}: {r:#}");
        }
        for name in ["s-reprojected-left.png", "s-reprojected-right.png"] {
            let image = image::open(dir.path().join(name)).expect(name).to_rgba8();
            assert_eq!(image.dimensions(), (320, 320));
        }
    });
}

#[test]
fn malformed_eye_fields_of_view_are_refused() {
    for bad in ["-52,43,-50", "10,-10,-40,40", "-95,43,-50,48", "a,b,c,d"] {
        let out = super::dmu(&[
            "render",
            "--plant-triangles",
            "10k",
            "--eye",
            "0,0,0",
            "--target",
            "1,0,0",
            "--stereo",
            &format!("--eye-fov={bad}"),
            "--shared-far-px",
            "0.5",
            "-o",
            "x.png",
        ]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--eye-fov"), "{bad}: {err}");
    }
}

/// Pairs that cannot be drawn are refused with a message naming the flag,
/// not a panic (regressions: an image wider than the device's largest
/// texture, an eye field of view so narrow that the grid's width overflowed,
/// and an eye separation that leaves no near part to draw, all panicked).
#[test]
fn pairs_that_cannot_be_drawn_are_refused() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let png = path(dir.path(), "refused.png");
        let wide = ["--size", "16000x16", "--eye-fov=-52,43,-50,48"];
        let narrow = ["--size", "64x64", "--eye-fov=10,10.0000000001,-40,40"];
        let no_ipd = ["--size", "64x64", "--ipd", "0"];
        let cases: [(&[&str], &str, &str); 5] = [
            (&wide, "--reproject", "make --size smaller"),
            (&wide, "--shared-far-px=0.5", "make --size smaller"),
            (&narrow, "--reproject", "--eye-fov"),
            (&narrow, "--shared-far-px=0.5", "--eye-fov"),
            (&no_ipd, "--shared-far-px=0.5", "--ipd 0"),
        ];
        for (extra, flag, reason) in cases {
            let mut args = vec![
                "--plant-triangles",
                "10k",
                "--eye",
                "4509000,5349750,13700",
                "--target",
                "4572000,5351750,14000",
                "--stereo",
                flag,
                "-o",
                &png,
            ];
            args.extend_from_slice(extra);
            let out = render(&args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{flag} {extra:?}: {err}");
            let flag_name = flag.split('=').next().unwrap();
            assert!(
                err.contains(flag_name) && err.contains(reason) && !err.contains("panicked"),
                "{flag} {extra:?}: {err}"
            );
        }
    });
}
