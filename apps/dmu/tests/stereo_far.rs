//! `dmu render --stereo --shared-far-px`: the pair with a shared far part
//! against the same pair drawn in full, with asymmetric eye fields of view.
//! Included from `tests.rs`.

use serde_json::Value;

use super::{path, render};

#[test]
fn shared_far_pair_matches_the_full_pair_within_its_bound() {
    let dir = tempfile::tempdir().unwrap();
    let png = path(dir.path(), "s.png");
    // Inside the plant, looking down the pipe rack (millimetres).
    let args = [
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
        "--shared-far-px",
        "0.5",
        "--frames",
        "2",
        "--json",
        "-o",
        &png,
    ];
    let Some(out) = render("shared_far_pair_matches_the_full_pair", &args) else {
        return;
    };
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
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
