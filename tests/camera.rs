use glam::Vec3;
use vizsim::camera::{parse_image_size, Camera, Projection, View};
use vizsim::render::clip_to_box;

#[test]
fn up_parallel_to_view_direction_is_an_error() {
    let err = Camera::new(
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, 10.0),
        Vec3::Z,
        Projection::Ortho,
        64,
        64,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("parallel"), "{err}");
}

#[test]
fn image_sizes_zero_or_absurd_are_errors() {
    assert!(parse_image_size("0x256").is_err());
    assert!(parse_image_size("256x100000").is_err());
    assert!(parse_image_size("256").is_err());
    // Too large for any integer type: out of range, not malformed.
    let e = parse_image_size("99999999999x1").unwrap_err().to_string();
    assert!(e.contains("each side must be 1..="), "{e}");
    assert!(parse_image_size("-1x1")
        .unwrap_err()
        .to_string()
        .contains("expected WxH"));
    assert_eq!(parse_image_size("320x200").unwrap(), (320, 200));
}

#[test]
fn views_parse_and_orbit_frames_are_five_degrees_apart() {
    assert_eq!(View::parse("front").unwrap(), View::Front);
    let v = View::parse("orbit:3/72").unwrap();
    assert_eq!(v.angle_deg(), 15.0);
    for bad in ["orbit:72/72", "orbit:1/0", "orbit:x/4", "side"] {
        assert!(View::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn front_view_looks_along_plus_y_with_x_to_the_right() {
    let cam =
        Camera::for_volume(Vec3::splat(63.0), View::Front, Projection::Ortho, 64, 64).unwrap();
    let (o_left, d) = cam.world_ray(0, 32);
    let (o_right, _) = cam.world_ray(63, 32);
    assert!((d - Vec3::Y).length() < 1e-6);
    assert!(o_right.x > o_left.x);
    let quarter = Camera::for_volume(
        Vec3::splat(63.0),
        View::Orbit { k: 18, n: 72 },
        Projection::Ortho,
        64,
        64,
    )
    .unwrap();
    let (_, d) = quarter.world_ray(32, 32);
    assert!(d.z.abs() < 1e-6 && (d.length() - 1.0).abs() < 1e-6);
    assert!(
        (d.dot(Vec3::Y)).abs() < 1e-5,
        "90 degrees from the front: {d}"
    );
}

#[test]
fn default_fit_spans_the_largest_extent_across_the_width() {
    // Volume 64 x 32 x 16 voxels: extent 63 x 31 x 15. Front view: x spans the image width.
    let dims = [64, 32, 16];
    let extent = Vec3::new(63.0, 31.0, 15.0);
    let cam = Camera::for_volume(extent, View::Front, Projection::Ortho, 128, 128).unwrap();
    let hits_row = |py: u32| -> Vec<bool> {
        (0..128)
            .map(|px| clip_to_box(&cam.voxel_ray(px, py, [1.0; 3]), dims).is_some())
            .collect()
    };
    let row = hits_row(64);
    // Every pixel of the middle row hits, since the box spans exactly the image width.
    assert!(row.iter().all(|&h| h));
    // Vertically the box is 15/63 of the width: top rows miss.
    assert!(!hits_row(0)[64]);
}

#[test]
fn perspective_rays_diverge_and_fit_the_volume() {
    let extent = Vec3::splat(63.0);
    let cam = Camera::for_volume(extent, View::Front, Projection::Persp, 64, 64).unwrap();
    let (eye_a, da) = cam.world_ray(0, 32);
    let (eye_b, db) = cam.world_ray(63, 32);
    assert_eq!(eye_a, eye_b);
    assert!(da.dot(db) < 0.999);
    // The centre ray hits the volume; corner rays of the frustum pass beside the front face.
    assert!(clip_to_box(&cam.voxel_ray(32, 32, [1.0; 3]), [64; 3]).is_some());
}

#[test]
fn camera_inside_the_volume_starts_rays_at_the_near_plane() {
    let mut cam = Camera::new(
        Vec3::splat(32.0),
        Vec3::new(32.0, 63.0, 32.0),
        Vec3::Z,
        Projection::Persp,
        16,
        16,
    )
    .unwrap();
    cam.near = 2.0;
    let ray = cam.voxel_ray(8, 8, [1.0; 3]);
    let (t0, t1) = clip_to_box(&ray, [64; 3]).unwrap();
    assert!((t0 - 2.0).abs() < 1e-5, "{t0}");
    assert!(t1 > 30.0);
}
