//! Area lights at VRT (direct light sampled on the emitters from each diffuse hit)
//! against closed forms: the irradiance on a plane under a uniform Lambertian disk (on
//! its axis) and under a rectangle (anywhere, by the form factor of a parallel
//! rectangle), read from the rendered radiance `rho / pi * E` of a diffuse receiver;
//! the `pi L A` an emitter sends, all of it found again on the walls of a closed box; and
//! the bits staying the same whatever the nodes and the cache.

mod common;
use common::*;
use glam::DVec3;
use magg_core::camera::CameraRig;
use magg_core::color::Rgb;
use magg_core::direct::area_irradiance;
use magg_core::scatter::Arrival;
use magg_core::scene::{Camera, DirectLight, Material, PatchDef, Scene};
use std::f64::consts::PI;

fn emitter(l: f64) -> Material {
    let mut m = material("lamp", 0.0, 0.0, 0.0);
    m.emit = Rgb::splat(l);
    m
}

/// A scene lit only by its emitters, their direct light at VRT.
fn at_vrt(patches: Vec<PatchDef>, materials: Vec<Material>) -> Scene {
    let mut s = scene(patches, materials, vec![]);
    s.settings.direct = DirectLight::Auto;
    s.settings.ambient = Rgb::BLACK;
    s
}

/// A floor of half-side `r` at y = 0, facing up.
fn floor(r: f64, material: u32) -> Vec<PatchDef> {
    quad(v(-r, 0.0, -r), v(-r, 0.0, r), v(r, 0.0, r), v(r, 0.0, -r), material, 2)
}

/// A disk of radius `r` at height `h`, facing down: a fan of `n` triangles.
fn disk(r: f64, h: f64, n: u32, material: u32) -> Vec<PatchDef> {
    let at = |k: u32| {
        let a = 2.0 * PI * k as f64 / n as f64;
        v(r * a.cos(), h, r * a.sin())
    };
    (0..n).map(|k| tri(v(0.0, h, 0.0), at(k), at(k + 1), material, 1)).collect()
}

/// A camera looking straight down at the floor from `height`.
fn looking_down(s: &mut Scene, height: f64, size: u32) {
    s.camera = Camera { eye: v(0.0, height, 0.0), look_at: v(0.0, 0.0, 0.0), up: v(0.0, 0.0, -1.0), fov_y_deg: 90.0 };
    s.settings.width = size;
    s.settings.height = size;
    s.settings.pixel_samples = 1;
}

/// Where the centre ray of pixel (x, y) meets the plane y = 0, if in front.
fn floor_point(rig: &CameraRig, x: u32, y: u32) -> Option<DVec3> {
    let r = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
    let t = -r.origin.y / r.direction.y;
    (t > 0.0).then(|| r.at(t))
}

/// Irradiance at height `h` below the corner of a parallel rectangle of sides `a` and `b`
/// and radiance `l` (the form factor of a differential area to a parallel rectangle,
/// times pi L), extended oddly to negative sides so that any rectangle is a sum of four.
fn corner(l: f64, h: f64, a: f64, b: f64) -> f64 {
    let (x, y) = (a.abs() / h, b.abs() / h);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    let f = l / 2.0 * (x / sx * (y / sx).atan() + y / sy * (x / sy).atan());
    f * a.signum() * b.signum()
}

/// Irradiance at `p` on the plane y = 0 from the rectangle `[x0, x1] x [z0, z1]` at height
/// `h` facing down, of radiance `l`.
fn rectangle_irradiance(l: f64, h: f64, [x0, x1, z0, z1]: [f64; 4], p: DVec3) -> f64 {
    let g = |x: f64, z: f64| corner(l, h, x - p.x, z - p.z);
    g(x1, z1) - g(x0, z1) - g(x1, z0) + g(x0, z0)
}

#[test]
fn the_disk_formula_and_the_rectangle_form_factor_agree_with_their_limits() {
    // A tiny rectangle is a point source: L A cos^2 / d^2 straight below it.
    let (l, h, a) = (2.0, 1.5, 1e-3);
    let e = rectangle_irradiance(l, h, [-a / 2.0, a / 2.0, -a / 2.0, a / 2.0], DVec3::ZERO);
    assert!((e / (l * a * a / (h * h)) - 1.0).abs() < 1e-5, "{e}");
    // A huge one is the whole sky: pi L.
    let e = rectangle_irradiance(l, 1e-3, [-10.0, 10.0, -10.0, 10.0], DVec3::ZERO);
    assert!((e / (PI * l) - 1.0).abs() < 1e-3, "{e}");
    // Outside its footprint, the difference of two rectangles sharing an edge.
    let p = v(2.0, 0.0, 0.0);
    let near = rectangle_irradiance(l, h, [-1.0, 1.0, -1.0, 1.0], p);
    let both = rectangle_irradiance(l, h, [-1.0, 3.0, -1.0, 1.0], p);
    let far = rectangle_irradiance(l, h, [1.0, 3.0, -1.0, 1.0], p);
    assert!((near + far - both).abs() < 1e-12 && near > 0.0);
}

#[test]
fn a_rendered_floor_under_a_rectangular_lamp_has_the_form_factor_irradiance() {
    // A 0.8 x 0.5 m lamp of 3 W m^-2 sr^-1 at 0.6 m, its centre off the camera's axis; a
    // white floor (rho 0.5) seen from above. Every pixel is rho / pi * E.
    let (l, h, rho) = (3.0, 0.6, 0.5);
    let rect = [-0.3, 0.5, -0.35, 0.15];
    let lamp =
        quad(v(rect[0], h, rect[2]), v(rect[1], h, rect[2]), v(rect[1], h, rect[3]), v(rect[0], h, rect[3]), 1, 2);
    let mut patches = floor(3.0, 0);
    patches.extend(lamp);
    let mut s = at_vrt(patches, vec![material("floor", rho, 0.0, 0.0), emitter(l)]);
    looking_down(&mut s, 0.3, 48);
    let (p, out) = prepare_and_run(&s);
    assert!(p.header.plan.direct_vrt && p.header.plan.area_samples() > 0, "{}", p.header.plan);
    assert_eq!(out.stats.light.reached.0[0], 0.0, "no pair deposits: the floor is lit at VRT");
    let rig = CameraRig::new(&s.camera, s.settings.width, s.settings.height);
    let (mut got_sum, mut want_sum, mut worst, mut squares, mut checked) = (0.0, 0.0, 0.0f64, 0.0, 0);
    for y in 0..s.settings.height {
        for x in 0..s.settings.width {
            let Some(q) = floor_point(&rig, x, y) else { continue };
            let want = rho / PI * rectangle_irradiance(l, h, rect, q);
            let got = out.frame.get(x, y)[0] as f64;
            got_sum += got;
            want_sum += want;
            worst = worst.max((got / want - 1.0).abs());
            squares += (got / want - 1.0).powi(2);
            checked += 1;
        }
    }
    let (mean, rms) = (got_sum / want_sum - 1.0, (squares / checked as f64).sqrt());
    println!(
        "{checked} pixels: mean {:+.4}%, rms {:.3}%, worst pixel {:.3}%",
        100.0 * mean,
        100.0 * rms,
        100.0 * worst
    );
    // Each pixel is one viewing ray's 16 shadow rays (two on each of the lamp's eight
    // elements): its error is the sampling error, about 1%; the mean over the image is
    // exact to far less.
    assert!(mean.abs() < 0.002, "mean radiance off by {:.4}%", 100.0 * mean);
    assert!(rms < 0.015 && worst < 0.06, "pixels off by {:.3}% rms, {:.3}% at worst", 100.0 * rms, 100.0 * worst);
}

#[test]
fn a_rendered_floor_on_the_axis_of_a_disk_lamp_has_pi_l_r2_over_h2_plus_r2() {
    // A disk of radius 0.4 (a fan of 96 triangles) at 0.5 m; the pixel at the image's
    // centre sees the floor on the disk's axis. The fan's area falls short of the disk's
    // by (1 - sin(2 pi / n) n / (2 pi)), 0.07%: inside the tolerance.
    let (l, h, r, rho) = (4.0, 0.5, 0.4, 0.6);
    let mut patches = floor(2.0, 0);
    patches.extend(disk(r, h, 96, 1));
    let mut s = at_vrt(patches, vec![material("floor", rho, 0.0, 0.0), emitter(l)]);
    looking_down(&mut s, 0.25, 9);
    // The middle pixel's rays straddle the axis: E varies by second order across it.
    s.settings.pixel_samples = 16;
    let (_, out) = prepare_and_run(&s);
    let want = rho / PI * PI * l * r * r / (h * h + r * r);
    let got = out.frame.get(4, 4)[0] as f64;
    println!("on the axis: {got} vs {want} ({:+.3}%)", 100.0 * (got / want - 1.0));
    assert!((got / want - 1.0).abs() < 0.01, "{got} vs {want}");
}

#[test]
fn the_irradiance_sampled_over_a_closed_box_adds_up_to_pi_l_a() {
    // A 0.3 m square lamp facing down inside a closed 2 m box: every watt it emits,
    // pi L A, lands on the box's walls. The irradiance that VRT's shadow rays estimate,
    // integrated over the walls (midpoint rule, 40 x 40 points a face), gives it back.
    let (l, a) = (3.0, 0.3);
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 4, true);
    let h = a / 2.0;
    patches.extend(quad(v(-h, 1.5, -h), v(h, 1.5, -h), v(h, 1.5, h), v(-h, 1.5, h), 1, 2));
    let s = at_vrt(patches, vec![material("white", 0.5, 0.0, 0.0), emitter(l)]);
    let p = magg_prepare::prepare(&s).unwrap();
    let mut view = view_of(&p);
    let mut scratch = magg_core::trace::TraceScratch::default();
    let n = 40;
    let mut flux = 0.0;
    // Each face of the box: its corner, two edge vectors and inward normal; the patch of
    // a point found by a ray cast from inside onto it.
    let faces: [(DVec3, DVec3, DVec3); 6] = [
        (v(-1.0, 0.0, -1.0), v(2.0, 0.0, 0.0), v(0.0, 0.0, 2.0)), // floor
        (v(-1.0, 2.0, -1.0), v(2.0, 0.0, 0.0), v(0.0, 0.0, 2.0)), // ceiling
        (v(-1.0, 0.0, -1.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)), // z = -1
        (v(-1.0, 0.0, 1.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)),  // z = 1
        (v(-1.0, 0.0, -1.0), v(0.0, 2.0, 0.0), v(0.0, 0.0, 2.0)), // x = -1
        (v(1.0, 0.0, -1.0), v(0.0, 2.0, 0.0), v(0.0, 0.0, 2.0)),  // x = 1
    ];
    let centre = v(0.0, 1.0, 0.0);
    for (o, e1, e2) in faces {
        let da = e1.cross(e2).length() / (n * n) as f64;
        for i in 0..n {
            for j in 0..n {
                let q = o + e1 * ((i as f64 + 0.5) / n as f64) + e2 * ((j as f64 + 0.5) / n as f64);
                // The viewing ray that would arrive there: from the box's centre, nudged
                // off the lamp's axis so that the lamp never hides the point.
                let from = centre + v(0.01, -0.3, 0.013);
                let d = (q - from).normalize();
                let hit = magg_core::trace::cast(
                    &mut view,
                    &mut scratch,
                    &magg_core::geometry::Ray::new(from, d),
                    0.0,
                    f64::INFINITY,
                    magg_core::trace::NO_PATCH,
                    false,
                )
                .unwrap()
                .expect("inside a closed box every ray hits");
                let prec = view.patch(hit.patch).unwrap();
                if s.patches[hit.patch as usize].material != 0 {
                    continue;
                }
                let at = Arrival::new(from + d * hit.t, d, magg_core::geometry::triangle_normal(&prec.v));
                let e = area_irradiance(&mut view, &mut scratch, &at, hit.patch, 16, None).unwrap();
                flux += e.0[0] * da;
            }
        }
    }
    let want = PI * l * a * a;
    println!("walls received {flux} W of pi L A = {want} W ({:+.3}%)", 100.0 * (flux / want - 1.0));
    assert!((flux / want - 1.0).abs() < 0.01, "{flux} vs {want}");
}

#[test]
fn area_light_images_at_vrt_do_not_depend_on_nodes_or_cache() {
    // A lamp, a block that casts a soft shadow (VRT's), one diffuse bounce; with a mirror
    // that carries the lamp's light on (LRT's), or without (the bounce is then gathered
    // at the block's contact with the floor).
    for with_mirror in [true, false] {
        let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 4, true);
        patches.extend(quad(v(-0.2, 1.9, -0.2), v(0.2, 1.9, -0.2), v(0.2, 1.9, 0.2), v(-0.2, 1.9, 0.2), 1, 2));
        let mut mirror = material("mirror", 0.0, 0.8, 0.0);
        mirror.diffuse = Rgb::splat(0.1);
        if with_mirror {
            patches.extend(quad(v(0.3, 0.2, -0.3), v(0.3, 0.2, 0.3), v(0.9, 0.2, 0.3), v(0.9, 0.2, -0.3), 2, 2));
        }
        patches.extend(boxed(v(-0.6, 0.0, -0.3), v(-0.2, 0.5, 0.1), 0, 2, false));
        let mut s = at_vrt(patches, vec![material("white", 0.6, 0.0, 0.0), emitter(4.0), mirror]);
        s.settings.diffuse_bounces = 1;
        s.settings.pixel_samples = 2;
        s.settings.gather_rays = 16;
        s.camera = Camera { eye: v(0.0, 1.0, 0.9), look_at: v(-0.2, 0.3, 0.0), up: v(0.0, 1.0, 0.0), fov_y_deg: 60.0 };
        let p = magg_prepare::prepare(&s).unwrap();
        let plan = &p.header.plan;
        assert!(plan.direct_vrt && plan.gathers(s.settings.gather_rays, &s.materials) != with_mirror, "{plan}");
        let a = run(&p, 1, None);
        let b = run(&p, 3, Some(12));
        assert_eq!(a.element_flux, b.element_flux, "mirror: {with_mirror}");
        assert_eq!(a.frame, b.frame, "mirror: {with_mirror}");
        assert!(a.frame.get(16, 16).iter().all(|c| *c > 0.0));
    }
}
