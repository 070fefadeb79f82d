//! Tests of the conversions: round trips, and what the wire may not carry.

use super::*;
use magg_core::scene::{Exposure, GridSpec, Spot};
use prost::Message;
use std::sync::Arc;

#[test]
fn cache_size_crosses_the_wire_with_zero_for_unlimited() {
    for c in [CacheSize::Unlimited, CacheSize::from_blocks(Some(1)), CacheSize::from_blocks(Some(40))] {
        assert_eq!(cache_size_from_wire(cache_size_to_wire(c)), c);
    }
    assert_eq!(cache_size_to_wire(CacheSize::Unlimited), 0);
    assert_eq!(cache_size_from_wire(7).blocks(), Some(7));
}

fn paper_header() -> Arc<SceneHeader> {
    let text = include_str!("../../../scenes/magg-paper.toml");
    let read = |p: &std::path::Path| std::fs::read(p);
    let scene = magg_core::scene::parse_scene_str("magg-paper.toml", text, "scenes".as_ref(), &read).unwrap();
    magg_prepare::prepare(&scene).unwrap().header
}

/// The header as it comes back from the wire: source locations are not sent.
fn as_received(h: &SceneHeader) -> SceneHeader {
    let mut h = h.clone();
    h.lights.iter_mut().for_each(|l| l.loc = wire_loc());
    h.materials.iter_mut().for_each(|m| m.loc = wire_loc());
    h
}

#[test]
fn prepared_header_round_trips_exactly() {
    let h = paper_header();
    let wire = v1::SceneHeader::from(&*h);
    let bytes = wire.encode_to_vec();
    let decoded = v1::SceneHeader::decode(bytes.as_slice()).unwrap();
    assert_eq!(SceneHeader::try_from(decoded).unwrap(), as_received(&h));
}

#[test]
fn exposure_spot_and_auto_grid_round_trip() {
    let mut h = (*paper_header()).clone();
    h.settings.exposure = Exposure::Fixed(2.5);
    h.settings.grid = GridSpec::Auto;
    h.lights[0].spot = Some(Spot { direction: DVec3::new(0.0, -1.0, 0.0), half_angle_deg: 30.0, falloff_deg: 10.0 });
    let wire = v1::SceneHeader::from(&h);
    assert!(wire.settings.as_ref().unwrap().grid.is_empty());
    assert_eq!(SceneHeader::try_from(wire).unwrap(), as_received(&h));
}

/// Converts the paper header after `f` spoils it; returns the error.
fn refused(f: impl FnOnce(&mut v1::SceneHeader)) -> ConvertError {
    let mut wire = v1::SceneHeader::from(&*paper_header());
    f(&mut wire);
    SceneHeader::try_from(wire).expect_err("a bad header was accepted")
}

fn field_of(e: &ConvertError) -> &str {
    match e {
        ConvertError::Missing { field } | ConvertError::Invalid { field, .. } => field,
        ConvertError::BlockSize { .. } => "block",
    }
}

#[test]
fn missing_sub_messages_are_refused() {
    assert_eq!(refused(|h| h.camera = None), ConvertError::Missing { field: "camera".into() });
    assert_eq!(field_of(&refused(|h| h.settings.as_mut().unwrap().ambient = None)), "settings.ambient");
    assert_eq!(field_of(&refused(|h| h.grid = None)), "grid");
    assert_eq!(field_of(&refused(|h| h.layout = None)), "layout");
    assert_eq!(field_of(&refused(|h| h.counts = None)), "counts");
    assert_eq!(field_of(&refused(|h| h.plan = None)), "plan");
    assert_eq!(field_of(&refused(|h| h.lights[0].position = None)), "lights[0].position");
}

#[test]
fn non_finite_numbers_are_refused() {
    let e = refused(|h| h.camera.as_mut().unwrap().eye.as_mut().unwrap().x = f64::NAN);
    assert_eq!(field_of(&e), "camera.eye.x");
    assert!(e.to_string().contains("NaN"), "{e}");
    let e = refused(|h| h.grid.as_mut().unwrap().max.as_mut().unwrap().z = f64::INFINITY);
    assert_eq!(field_of(&e), "grid.max.z");
    assert_eq!(field_of(&refused(|h| h.energy_quantum = f64::NAN)), "energy_quantum");
    assert_eq!(field_of(&refused(|h| h.energy_quantum = 0.0)), "energy_quantum");
    assert_eq!(field_of(&refused(|h| h.settings.as_mut().unwrap().element_size = -0.1)), "settings.element_size");
}

#[test]
fn bad_grids_are_refused() {
    assert_eq!(field_of(&refused(|h| h.grid.as_mut().unwrap().dims = vec![8, 7])), "grid.dims");
    assert_eq!(field_of(&refused(|h| h.grid.as_mut().unwrap().dims = vec![8, 0, 6])), "grid.dims");
    let e = refused(|h| h.grid.as_mut().unwrap().dims = vec![u32::MAX, u32::MAX, u32::MAX]);
    assert_eq!(field_of(&e), "grid.dims");
    let e = refused(|h| {
        h.grid.as_mut().unwrap().cell_first_block.pop();
    });
    assert_eq!(field_of(&e), "grid.cell_first_block");
    let e = refused(|h| h.grid.as_mut().unwrap().cell_first_block[0] = 1_000_000);
    assert_eq!(field_of(&e), "grid.cell_first_block[0]");
    let e = refused(|h| h.grid.as_mut().unwrap().min = Some(v1::Vec3 { x: 9.0, y: 9.0, z: 9.0 }));
    assert_eq!(field_of(&e), "grid");
    assert_eq!(field_of(&refused(|h| h.counts.as_mut().unwrap().subspaces += 1)), "counts.subspaces");
}

#[test]
fn inconsistent_layouts_are_refused() {
    let e = refused(|h| {
        let l = h.layout.as_mut().unwrap();
        std::mem::swap(&mut l.patch_base, &mut l.element_base);
    });
    assert_eq!(field_of(&e), "layout");
    assert_eq!(field_of(&refused(|h| h.layout.as_mut().unwrap().total += 1)), "counts.vertex_blocks");
    assert_eq!(field_of(&refused(|h| h.counts.as_mut().unwrap().elements += 10_000)), "counts.element_blocks");
    assert_eq!(field_of(&refused(|h| h.counts.as_mut().unwrap().patches = 0)), "counts.patch_blocks");
    let e = refused(|h| h.counts.as_mut().unwrap().shaded_patches = SHADINGS_PER_BLOCK as u32 + 1);
    assert_eq!(field_of(&e), "counts.shading_blocks");
    let e = refused(|h| h.layout.as_mut().unwrap().total = MAX_BLOCKS + 1);
    assert_eq!(field_of(&e), "layout.total");
    let e = refused(|h| h.settings.as_mut().unwrap().max_elements = 1000);
    assert_eq!(field_of(&e), "counts.elements");
}

/// The paper's scene traced through a BVH (the file asks for the paper's grid).
fn bvh_header() -> Arc<SceneHeader> {
    let text = include_str!("../../../scenes/magg-paper.toml");
    let text = text.replace("accel = \"grid\"", "accel = \"bvh\"");
    let read = |p: &std::path::Path| std::fs::read(p);
    let scene = magg_core::scene::parse_scene_str("magg-paper.toml", &text, "scenes".as_ref(), &read).unwrap();
    magg_prepare::prepare(&scene).unwrap().header
}

#[test]
fn the_acceleration_structure_and_its_blocks_must_agree() {
    let h = bvh_header();
    let wire = v1::SceneHeader::from(&*h);
    assert_eq!(wire.settings.as_ref().unwrap().accel, v1::Accel::Bvh as i32);
    assert!(h.bvh.nodes > 0 && h.counts.bvh_blocks > 0);
    assert_eq!(SceneHeader::try_from(wire).unwrap(), as_received(&h));
    // The grid's header goes and comes back too.
    let grid = paper_header();
    assert_eq!(grid.settings.accel, magg_core::scene::Accel::Grid);
    assert!(grid.counts.subspace_blocks > 0 && grid.bvh == Default::default());
    let back = SceneHeader::try_from(v1::SceneHeader::from(&*grid)).unwrap();
    assert_eq!(back, as_received(&grid));
    assert_eq!(field_of(&refused(|h| h.settings.as_mut().unwrap().accel = 7)), "settings.accel");
    // A BVH scene announced as a grid one (and the reverse) is refused.
    let refused_bvh = |f: &dyn Fn(&mut v1::SceneHeader)| {
        let mut wire = v1::SceneHeader::from(&*h);
        f(&mut wire);
        SceneHeader::try_from(wire).expect_err("a bad header was accepted")
    };
    let e = refused_bvh(&|h| h.settings.as_mut().unwrap().accel = v1::Accel::Grid as i32);
    assert_eq!(field_of(&e), "bvh.nodes");
    assert_eq!(field_of(&refused_bvh(&|h| h.bvh = None)), "counts.bvh_blocks");
    assert_eq!(field_of(&refused_bvh(&|h| h.bvh.as_mut().unwrap().nodes += 32)), "bvh.node_blocks");
    let e = refused_bvh(&|h| h.bvh.as_mut().unwrap().triangles = h.counts.as_ref().unwrap().patches + 1);
    assert_eq!(field_of(&e), "bvh.triangles");
    assert_eq!(field_of(&refused_bvh(&|h| h.bvh.as_mut().unwrap().triangles = 0)), "bvh.triangle_blocks");
    assert_eq!(field_of(&refused_bvh(&|h| h.layout.as_mut().unwrap().bvh_base += 1)), "counts.subspace_blocks");
    let e = refused(|h| h.settings.as_mut().unwrap().accel = v1::Accel::Bvh as i32);
    assert!(!field_of(&e).is_empty(), "a grid scene announced as a BVH one was accepted");
}

#[test]
fn bad_materials_and_lights_are_refused() {
    fn m(h: &mut v1::SceneHeader) -> &mut v1::Material {
        &mut h.materials[0]
    }
    let e = refused(|h| m(h).diffuse.as_mut().unwrap().g = 1.5);
    assert_eq!(field_of(&e), "materials[0].diffuse.g");
    assert_eq!(field_of(&refused(|h| m(h).mirror.as_mut().unwrap().r = -0.1)), "materials[0].mirror.r");
    let e = refused(|h| m(h).mirror = Some(v1::Rgb { r: 0.5, g: 0.5, b: 0.5 }));
    assert!(field_of(&e).starts_with("materials[0].diffuse+mirror+transmit"), "{e}");
    assert_eq!(field_of(&refused(|h| m(h).ior = 0.5)), "materials[0].ior");
    assert_eq!(field_of(&refused(|h| m(h).ior = 4.5)), "materials[0].ior");
    assert_eq!(field_of(&refused(|h| h.materials.clear())), "materials");
    let e = refused(|h| h.lights[0].intensity.as_mut().unwrap().b = -1.0);
    assert_eq!(field_of(&e), "lights[0].intensity.b");
    let e = refused(|h| h.lights[0].intensity.as_mut().unwrap().r = f64::INFINITY);
    assert_eq!(field_of(&e), "lights[0].intensity.r");
    let e = refused(|h| {
        h.lights[0].spot =
            Some(v1::Spot { direction: Some(v1::Vec3::default()), half_angle_deg: 10.0, falloff_deg: 0.0 })
    });
    assert_eq!(field_of(&e), "lights[0].spot.direction");
    assert_eq!(field_of(&refused(|h| h.camera.as_mut().unwrap().fov_y_deg = 180.0)), "camera.fov_y_deg");
}

#[test]
fn settings_out_of_the_parsers_ranges_are_refused() {
    type Spoil = fn(&mut v1::RenderSettings);
    let cases: [(Spoil, &str); 15] = [
        (|s| s.width = 0, "settings.width"),
        (|s| s.height = 16385, "settings.height"),
        (|s| s.pixel_samples = 4097, "settings.pixel_samples"),
        (|s| s.light_rays = 0, "settings.light_rays"),
        (|s| s.light_rays = 1_000_001, "settings.light_rays"),
        (|s| s.bounce_rays = 0, "settings.bounce_rays"),
        (|s| s.bounce_rays = 4097, "settings.bounce_rays"),
        (|s| s.gather_rays = 4097, "settings.gather_rays"),
        (|s| s.lrt_depth = 33, "settings.lrt_depth"),
        (|s| s.vrt_depth = 33, "settings.vrt_depth"),
        (|s| s.diffuse_bounces = 17, "settings.diffuse_bounces"),
        (|s| s.exposure = -1.0, "settings.exposure"),
        (|s| s.grid = vec![4, 4], "settings.grid"),
        (|s| s.grid = vec![4, 0, 4], "settings.grid"),
        (|s| s.max_elements = 0, "settings.max_elements"),
    ];
    for (spoil, field) in cases {
        assert_eq!(field_of(&refused(|h| spoil(h.settings.as_mut().unwrap()))), field);
    }
}

#[test]
fn plan_depths_over_the_limit_are_refused() {
    assert_eq!(field_of(&refused(|h| h.plan.as_mut().unwrap().lrt_depth = 33)), "plan.lrt_depth");
    assert_eq!(field_of(&refused(|h| h.plan.as_mut().unwrap().vrt_depth = 1000)), "plan.vrt_depth");
    let e = refused(|h| h.plan.as_mut().unwrap().reasons = vec![String::new(); MAX_REASONS + 1]);
    assert_eq!(field_of(&e), "plan.reasons");
}

#[test]
fn element_energies_come_in_threes() {
    let r = v1::GetEnergiesReply::from(magg_core::cluster::ForkReport {
        elements: vec![4, 9],
        energy: vec![[1, 2, 3], [4, 5, -6]],
        ..Default::default()
    });
    assert_eq!(element_energies(&r).unwrap().collect::<Vec<_>>(), vec![(4, [1, 2, 3]), (9, [4, 5, -6])]);
    let short = v1::GetEnergiesReply { energy: r.energy.slice(..40), ..r.clone() };
    let e = element_energies(&short).err().unwrap();
    assert!(e.to_string().contains("3 values (24 bytes) for each of 2 elements"), "{e}");
    let cut = v1::GetEnergiesReply { elements: vec![0x84].into(), ..r };
    let e = element_energies(&cut).err().unwrap();
    assert!(e.to_string().contains("GetEnergiesReply.elements"), "{e}");
}

#[test]
fn blocks_must_be_exactly_2048_bytes() {
    let mut b = Box::new([0u8; BLOCK_SIZE]);
    b[0] = 1;
    b[BLOCK_SIZE - 1] = 255;
    let (id, back) = block_from_wire(block_to_wire(42, &b)).unwrap();
    assert_eq!((id, back), (42, b));
    for len in [0, BLOCK_SIZE - 1, BLOCK_SIZE + 1] {
        let e = block_from_wire(v1::Block { id: 7, data: vec![0; len].into() }).unwrap_err();
        assert_eq!(e, ConvertError::BlockSize { id: 7, len });
    }
}

#[test]
fn pixel_rows_are_the_bytes_of_a_packed_repeated_float() {
    let px = [0.25f32, -1.5, 3.0e-7, f32::MAX, 0.0, 1.0];
    // A row as `message Row { uint32 y = 1; repeated float rgb = 2; }` encodes it.
    let mut old = Vec::new();
    prost::encoding::uint32::encode(1, &7, &mut old);
    prost::encoding::float::encode_packed(2, &px, &mut old);
    let row = v1::Row::decode(old.as_slice()).unwrap();
    assert_eq!(row.y, 7);
    assert_eq!(pixels_from_wire(&row.rgb).collect::<Vec<_>>(), px);
    let mut triples = [[0f32; 3]; 2];
    pixels_into(&row.rgb, &mut triples);
    assert_eq!(triples.concat(), px[..6]);
    let new = v1::Row { y: 7, rgb: pixels_to_wire(px) };
    assert_eq!(new.encode_to_vec(), old);
}

fn area_header() -> Arc<SceneHeader> {
    let text = include_str!("../../../scenes/area.toml");
    let read = |p: &std::path::Path| std::fs::read(p);
    let scene = magg_core::scene::parse_scene_str("area.toml", text, "scenes".as_ref(), &read).unwrap();
    magg_prepare::prepare(&scene).unwrap().header
}

#[test]
fn emitters_and_emitting_materials_round_trip() {
    let h = area_header();
    assert_eq!(h.emitters.len(), 8);
    assert!(h.plan.area_lights && h.materials.iter().any(|m| m.is_emitter()));
    let decoded = v1::SceneHeader::decode(v1::SceneHeader::from(&*h).encode_to_vec().as_slice()).unwrap();
    assert_eq!(SceneHeader::try_from(decoded).unwrap(), as_received(&h));
    // A material that emits nothing leaves the field out.
    assert!(v1::SceneHeader::from(&*paper_header()).materials.iter().all(|m| m.emit.is_none()));
}

#[test]
fn bad_emitters_are_refused() {
    let spoil = |f: &dyn Fn(&mut v1::SceneHeader)| {
        let mut wire = v1::SceneHeader::from(&*area_header());
        f(&mut wire);
        SceneHeader::try_from(wire).expect_err("a bad header was accepted")
    };
    assert_eq!(field_of(&spoil(&|h| h.emitters[1].element = h.emitters[0].element)), "emitters[1].element");
    assert_eq!(field_of(&spoil(&|h| h.emitters[0].element = u32::MAX)), "emitters[0].element");
    assert_eq!(field_of(&spoil(&|h| h.emitters[2].power.as_mut().unwrap().g = -1.0)), "emitters[2].power.g");
    assert_eq!(field_of(&spoil(&|h| h.emitters[2].power = None)), "emitters[2].power");
    let lamp = |h: &mut v1::SceneHeader| {
        h.materials.iter_mut().find(|m| m.emit.is_some()).unwrap().emit.as_mut().unwrap().r = f64::NAN
    };
    assert!(field_of(&spoil(&lamp)).ends_with(".emit.r"));
}
