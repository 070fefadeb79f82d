//! Where a light ray lands. A pair's primary rays, cast towards its element, are
//! answered together ([`land_primaries`]: occlusion queries of rays from one origin walk
//! the BVH in packets) and then, each in the pair's ray order, deposit on the element
//! and scatter on: the same tail for a point light's rays and an emitter's. A secondary
//! ray is followed to its nearest hit ([`follow_one`]), deposits there and scatters on.
//! [`scatter`] splits the flux at a surface into what is absorbed, what ends diffusely
//! and the secondary rays (mirror, Fresnel-weighted reflection and refraction, diffuse
//! bounces) it spawns.

use super::rays::{Branch, RayId};
use super::result::{LrtTally, RawDeposit};
use super::waves::PairTrees;
use crate::blocks::{BlockError, ElementRecord, PatchRecord};
use crate::color::Rgb;
use crate::geometry::{cosine_hemisphere, triangle_normal, Ray};
use crate::rng::halton35;
use crate::scatter::{arrive, offset_scale, Arrival, Dielectric};
use crate::scene::Material;
use crate::subdivision::locate;
use crate::trace::{cast, occluded_all, TraceScratch};
use crate::view::SceneView;
use glam::DVec3;

/// Secondary rays whose flux falls below this fraction of their primary ray's flux are
/// cut off (and counted as such in the tally).
pub const MIN_RELATIVE_FLUX: f64 = 1e-6;

/// A secondary light ray waiting to be followed.
pub(super) struct Pending {
    ray: Ray,
    flux: Rgb,
    from_patch: u32,
    specular: u32,
    diffuse: u32,
    floor: f64,
    /// How it left the surface that spawned it.
    pub(super) branch: Branch,
    /// Who it is in its pair.
    id: RayId,
}

/// The element a pair's primary rays are cast onto, as each ray's tail needs it.
pub(super) struct Target<'a> {
    /// The pair's light source (a point light's index, or `lights + k`).
    pub light: u32,
    /// The pair's element.
    pub element: u32,
    /// The lattice element it lies in (its face) and that element's patch.
    pub erec: ElementRecord,
    pub prec: PatchRecord,
    /// The patch's geometric normal.
    pub normal: DVec3,
    /// The patch's material.
    pub material: Option<&'a Material>,
    /// Diffuse bounce rays each primary ray sends, and the pair's offset of their
    /// strata.
    pub fan: u32,
    pub offset: (f64, f64),
}

/// The tail of a pair's primary rays, queued in `trees.shots` (ray number, flux, distance
/// to the element's plane) with their occlusion queries in `trees.bundle`: the queries
/// answered together, then each ray in order. A blocked ray counts as occluded; one that
/// reaches the element's back of a one-sided material is absorbed; the others arrive
/// (shading normal, texture), deposit their flux on the element unless the plan computes
/// direct light at VRT ([`crate::plan::EffectsPlan::deposits_direct`]), and scatter on, their diffuse bounce
/// stratified over the pair's rays ([`Strata`]).
pub(super) fn land_primaries(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    trees: &mut PairTrees,
    tally: &mut LrtTally,
    target: &Target<'_>,
    out: &mut Vec<RawDeposit>,
) -> Result<(), BlockError> {
    let header = view.header.clone();
    let Target { light, element, erec, prec, normal, material, fan, offset } = *target;
    let (shots, bundle, mut occluded) =
        (std::mem::take(&mut trees.shots), std::mem::take(&mut trees.bundle), std::mem::take(&mut trees.occluded));
    let answered = occluded_all(view, scratch, &bundle, &mut occluded);
    let landed = answered.and_then(|()| {
        for ((&(k, flux, t_plane), b), &blocked) in shots.iter().zip(&bundle).zip(&occluded) {
            if blocked {
                tally.occluded = tally.occluded.add(flux);
                continue;
            }
            tally.reached = tally.reached.add(flux);
            let (ray, w) = (b.ray, b.ray.direction);
            if material.is_some_and(|m| m.refuses(w, normal)) {
                // The back of a one-sided patch: absorbed, nothing deposited or reflected.
                tally.absorbed = tally.absorbed.add(flux);
                continue;
            }
            let floor = flux.max_channel() * MIN_RELATIVE_FLUX;
            // Shading normals bend specular directions and a texture colours what bounces
            // diffusely (deposits are flux, taken on the geometric surface).
            let (at, albedo) = arrive(view, &prec, ray.at(t_plane), w, normal, None)?;
            let bounce = Some(Strata { first: k * fan, count: fan, offset });
            let s = Surface { at, albedo, material: prec.material, patch: erec.patch };
            let id = RayId::primary(header.settings.seed, light, element, k);
            scatter(view, id, &mut trees.spawned, tally, s, bounce, flux, 0, 0, floor);
            let deposit = header.plan.deposits_direct().then_some(RawDeposit::On(element, flux));
            trees.root(view, scratch, tally, deposit, out)?;
        }
        Ok(())
    });
    (trees.shots, trees.bundle, trees.occluded) = (shots, bundle, occluded);
    landed
}

/// Follows secondary ray `s`: returns what it deposits where it arrives (raw: under the
/// lattice element it reached), and pushes the rays it spawns there onto `spawned`.
pub(super) fn follow_one(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    spawned: &mut Vec<Pending>,
    tally: &mut LrtTally,
    s: &Pending,
) -> Result<Option<RawDeposit>, BlockError> {
    view.counters.light_rays += 1;
    let tmin = offset_scale(s.ray.origin);
    let Some(hit) = cast(view, scratch, &s.ray, tmin, f64::INFINITY, s.from_patch, false)? else {
        tally.escaped = tally.escaped.add(s.flux);
        return Ok(None);
    };
    let hp = view.patch(hit.patch)?;
    let hn = triangle_normal(&hp.v);
    if view.header.materials.get(hp.material as usize).is_some_and(|m| m.refuses(s.ray.direction, hn)) {
        tally.absorbed = tally.absorbed.add(s.flux);
        return Ok(None);
    }
    let (local, w) = locate(hp.subdivisions, hit.bary);
    let deposit = RawDeposit::Under { element: hp.element_on_face(local, s.ray.direction), w, flux: s.flux };
    let (at, albedo) = arrive(view, &hp, s.ray.at(hit.t), s.ray.direction, hn, Some(hit.bary))?;
    let surface = Surface { at, albedo, material: hp.material, patch: hit.patch };
    scatter(view, s.id, spawned, tally, surface, None, s.flux, s.specular, s.diffuse, s.floor);
    Ok(Some(deposit))
}

/// Where a light ray arrived: the point and its frame, the texture's albedo there, the
/// patch and its material.
struct Surface {
    at: Arrival,
    albedo: Rgb,
    material: u32,
    patch: u32,
}

/// Stratified samples of the diffuse bounce's direction for one primary light ray:
/// `count` points of the pair's Halton (3, 5) sequence from index `first`, shifted by
/// `offset` (Cranley-Patterson rotation), each sending an equal share of the flux.
#[derive(Clone, Copy, Debug)]
struct Strata {
    first: u32,
    count: u32,
    offset: (f64, f64),
}

/// Splits the flux arriving at a surface point into absorbed, diffusely ended and
/// secondary rays, per the material and the effects plan. `bounce` holds the stratified
/// samples of the diffuse bounce's directions for a pair's primary ray (its rays bounce
/// in directions spread evenly over the hemisphere, so the light they carry on lands as
/// evenly), among which the diffuse flux is shared; deeper bounces draw one direction
/// from the generator of `from`, the ray that arrived.
#[allow(clippy::too_many_arguments)]
fn scatter(
    view: &SceneView,
    from: RayId,
    stack: &mut Vec<Pending>,
    tally: &mut LrtTally,
    surface: Surface,
    bounce: Option<Strata>,
    flux: Rgb,
    specular: u32,
    diffuse: u32,
    floor: f64,
) {
    let Surface { at, albedo, material, patch } = surface;
    let header = &view.header;
    let plan = &header.plan;
    let Some(m) = header.materials.get(material as usize) else {
        tally.absorbed = tally.absorbed.add(flux);
        return;
    };
    // A texture scales the diffuse part; what it takes away is absorbed.
    let rho = m.diffuse.mul(albedo);
    let absorbed = Rgb([
        (1.0 - rho.0[0] - m.mirror.0[0] - m.transmit.0[0]).max(0.0),
        (1.0 - rho.0[1] - m.mirror.0[1] - m.transmit.0[1]).max(0.0),
        (1.0 - rho.0[2] - m.mirror.0[2] - m.transmit.0[2]).max(0.0),
    ]);
    tally.absorbed = tally.absorbed.add(flux.mul(absorbed));

    let (base, mut path) = (stack.len(), None);
    let mut push = |tally: &mut LrtTally, branch: Branch, dir: DVec3, f: Rgb, spec: u32, diff: u32| {
        if f.is_black() {
            return;
        }
        if f.max_channel() < floor {
            tally.cut = tally.cut.add(f);
            return;
        }
        let path = *path.get_or_insert_with(|| from.path());
        let (ray, id) = (at.spawn(dir), from.child(path, stack.len() - base));
        stack.push(Pending { ray, flux: f, from_patch: patch, specular: spec, diffuse: diff, floor, branch, id });
    };

    // Specular parts.
    let spec_flux_mirror = flux.mul(m.mirror);
    let spec_flux_transmit = flux.mul(m.transmit);
    if specular < plan.lrt_depth {
        if !spec_flux_mirror.is_black() {
            push(tally, Branch::Mirror, at.reflected(), spec_flux_mirror, specular + 1, diffuse);
        }
        if !spec_flux_transmit.is_black() {
            match at.dielectric(m.ior, plan.refraction) {
                Dielectric::Split { fresnel, refracted } => {
                    let (reflected, through) =
                        (spec_flux_transmit.scale(fresnel), spec_flux_transmit.scale(1.0 - fresnel));
                    push(tally, Branch::Reflected, at.reflected(), reflected, specular + 1, diffuse);
                    push(tally, Branch::Refracted, refracted, through, specular + 1, diffuse);
                }
                Dielectric::Reflected => {
                    push(tally, Branch::Reflected, at.reflected(), spec_flux_transmit, specular + 1, diffuse)
                }
            }
        }
    } else {
        tally.cut = tally.cut.add(spec_flux_mirror).add(spec_flux_transmit);
    }

    // Diffuse part.
    let diff_flux = flux.mul(rho);
    if diff_flux.is_black() {
        return;
    }
    if diffuse < plan.diffuse_bounces {
        match bounce {
            Some(Strata { first, count, offset: (bx, by) }) => {
                // (One share of one is the whole flux, exactly: x * 1.0 == x.)
                let share = diff_flux.scale(1.0 / count as f64);
                for j in 0..count {
                    let (u0, u1) = halton35(first + j, bx, by);
                    push(tally, Branch::Diffuse, cosine_hemisphere(at.normal, u0, u1), share, specular, diffuse + 1);
                }
            }
            None => {
                let mut rng = from.rng();
                let (u0, u1) = (rng.next_f64(), rng.next_f64());
                push(tally, Branch::Diffuse, cosine_hemisphere(at.normal, u0, u1), diff_flux, specular, diffuse + 1);
            }
        }
    } else {
        tally.diffuse_end = tally.diffuse_end.add(diff_flux);
    }
}
