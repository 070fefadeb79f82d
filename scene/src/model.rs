//! The parsed scene: camera, render settings, lights, materials and triangle patches.
//!
//! This is the form every front end (TOML files, OBJ/MTL meshes, tests building scenes
//! in code) produces and preprocessing consumes. All values here have been validated:
//! finite, in range, references resolved.

use crate::color::Rgb;
use glam::DVec3;

/// Where an entity came from, so that later errors can name the file and line.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SourceLoc {
    /// File name as the user gave it (or a label such as `<inline>`), shared: the
    /// patches of a mesh all point at one copy rather than each holding its own.
    pub file: std::sync::Arc<str>,
    /// 1-based line number, 0 when unknown.
    pub line: u32,
}

impl std::fmt::Display for SourceLoc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}", self.file, self.line)
        } else {
            write!(f, "{}", self.file)
        }
    }
}

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// Point the camera looks at.
    pub look_at: DVec3,
    /// Up direction (need not be orthogonal to the view direction).
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
}

/// A camera path (`[camera_path]` in a scene file): keyframes spread evenly over
/// `frames` frames (the first key on frame 0, the last on the last frame), the camera
/// of each frame interpolated linearly between its two neighbouring keys. The light
/// pass is view-independent, so one light pass serves every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    /// The keyframes, at least one.
    pub keys: Vec<Camera>,
    /// Frames to render, at least one.
    pub frames: u32,
    /// Where it was defined.
    pub loc: SourceLoc,
}

impl CameraPath {
    /// The camera of `frame` (clamped to the last frame). Frames that fall on a key get
    /// that key exactly.
    pub fn camera_at(&self, frame: u32) -> Camera {
        let Some(first) = self.keys.first() else {
            return Camera {
                eye: DVec3::ZERO,
                look_at: DVec3::new(0.0, 0.0, -1.0),
                up: DVec3::new(0.0, 1.0, 0.0),
                fov_y_deg: 45.0,
            };
        };
        let (k, n) = (self.keys.len() as u64 - 1, self.frames.max(1) as u64 - 1);
        if k == 0 || n == 0 {
            return first.clone();
        }
        // Position along the keys: frame * k / n, kept as an integer ratio so that frames
        // on keys are exact.
        let num = frame.min(n as u32) as u64 * k;
        let (seg, rem) = ((num / n) as usize, num % n);
        let a = &self.keys[seg];
        if rem == 0 {
            return a.clone();
        }
        let b = &self.keys[(seg + 1).min(self.keys.len() - 1)];
        let t = rem as f64 / n as f64;
        Camera {
            eye: a.eye.lerp(b.eye, t),
            look_at: a.look_at.lerp(b.look_at, t),
            up: a.up.lerp(b.up, t),
            fov_y_deg: a.fov_y_deg * (1.0 - t) + b.fov_y_deg * t,
        }
    }

    /// The camera of every frame, in order.
    pub fn cameras(&self) -> Vec<Camera> {
        (0..self.frames).map(|f| self.camera_at(f)).collect()
    }
}

/// Uniform grid resolution: explicit, or chosen from the patch count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridSpec {
    /// About `k * cbrt(patches)` cells along the longest axis, cells near cubic.
    Auto,
    /// Exactly these many subspaces along x, y, z.
    Fixed([u32; 3]),
}

/// The acceleration structure rays are cast through. Both give the same hits, bit for
/// bit (the nearest patch, ties to the lower id, by the same watertight test); only the
/// speed and the blocks a node reads differ.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Accel {
    /// A bounding volume hierarchy (binned SAH), packed in 2 KB blocks: the default.
    #[default]
    Bvh,
    /// The paper's uniform grid of subspaces, walked by 3D-DDA.
    Grid,
}

impl Accel {
    /// Its name in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Accel::Bvh => "bvh",
            Accel::Grid => "grid",
        }
    }

    /// The structure called `name` ("bvh" or "grid").
    pub fn parse(name: &str) -> Option<Accel> {
        match name {
            "bvh" => Some(Accel::Bvh),
            "grid" => Some(Accel::Grid),
            _ => None,
        }
    }
}

/// Where direct light from point and spot lights is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DirectLight {
    /// The effects plan decides (`magg_core::plan::EffectsPlan::for_scene`): at VRT unless
    /// the scene has too many lights for a shadow ray per light at every hit to pay.
    #[default]
    Auto,
    /// At each diffuse hit of a viewing ray, with one shadow ray per light: shadows as
    /// sharp as the pixels; the elements carry only what LRT alone can (light via mirrors
    /// and glass, diffuse bounces).
    Vrt,
    /// The paper's way: light rays deposit direct light on elements, interpolated at VRT.
    Lrt,
}

impl DirectLight {
    /// Its name in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DirectLight::Auto => "auto",
            DirectLight::Vrt => "vrt",
            DirectLight::Lrt => "lrt",
        }
    }

    /// The choice called `name` ("auto", "vrt" or "lrt").
    pub fn parse(name: &str) -> Option<DirectLight> {
        match name {
            "auto" => Some(DirectLight::Auto),
            "vrt" => Some(DirectLight::Vrt),
            "lrt" => Some(DirectLight::Lrt),
            _ => None,
        }
    }
}

/// Tone-mapping exposure for the PNG output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// Scale so that the 99th percentile of pixel luminance maps to 0.8.
    Auto,
    /// Multiply linear radiance by this factor before tone mapping.
    Fixed(f64),
}

/// Most diffuse bounce rays per light ray (`[render] bounce_rays`).
pub const MAX_BOUNCE_RAYS: u32 = 4096;

/// Most gather rays per viewing ray (`[render] gather_rays`).
pub const MAX_GATHER_RAYS: u32 = 4096;

/// Most levels of adaptive element refinement (`[render] refine`). The tracer's descent
/// from a lattice element to the leaf holding a point is bounded by it too.
pub const MAX_REFINE_LEVELS: u32 = 6;

/// Every accuracy knob and output setting of a render.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Viewing rays per pixel (stratified, anti-aliasing).
    pub pixel_samples: u32,
    /// Target element edge length (scene units); a patch is split into n*n elements
    /// with n = ceil(longest edge / element_size) unless the patch fixes n itself.
    pub element_size: f64,
    /// Primary light rays per (light, element) pair.
    pub light_rays: u32,
    /// Diffuse bounce rays sent from each light ray's hit by a pair traced only for its
    /// bounce (direct light at VRT, a diffuse target): such a pair casts
    /// `light_rays / bounce_rays` light rays (rounded up), each sending `bounce_rays`
    /// stratified bounce directions with an equal share of its flux, so that it still
    /// sends `light_rays` bounce rays for fewer light rays. 1 is one bounce per light ray.
    pub bounce_rays: u32,
    /// Rays a viewing ray's diffuse hit gathers the bounced light with where the
    /// elements cannot hold it (next to elements that received no light: a contact with
    /// another surface, `magg_core::energy::gather_vertices`), each with a shadow ray per
    /// light at its own hit; 0 interpolates everywhere. Only where the elements hold
    /// nothing but one diffuse bounce of direct light computed at VRT
    /// (`magg_core::plan::EffectsPlan::gathers`).
    pub gather_rays: u32,
    /// Maximum specular bounces of light rays (mirror, refraction) after the first hit.
    pub lrt_depth: u32,
    /// Maximum specular bounces of viewing rays.
    pub vrt_depth: u32,
    /// Diffuse-to-diffuse bounces of light rays (0 = paper's ambient term instead).
    pub diffuse_bounces: u32,
    /// Constant ambient irradiance-like term, used only when `diffuse_bounces == 0`.
    pub ambient: Rgb,
    /// Acceleration structure of ray casting.
    pub accel: Accel,
    /// Where direct light is computed (LRT onto elements, or VRT with shadow rays).
    pub direct: DirectLight,
    /// The paper's receiving (`faces = "shared"`): one element holds the light arriving
    /// on either face of its patch and shows it on both. By default (`"apart"`) patches
    /// of two-sided diffuse materials get back elements
    /// ([`Material::has_back_face`]).
    pub shared_faces: bool,
    /// Levels of adaptive element refinement (0: none): after a pilot light pass, the
    /// elements whose light differs sharply from a neighbour's are split in four, up to
    /// this many times (Heckbert 1990).
    pub refine: u32,
    /// The contrast `|a - b| / (a + b)` of two neighbouring elements' irradiance above
    /// which refinement splits them.
    pub refine_contrast: f64,
    /// Subspace grid resolution (with [`Accel::Grid`]).
    pub grid: GridSpec,
    /// Seed of every random choice (rays are seeded from it, the pair and the pixel).
    pub seed: u64,
    /// Tone-mapping exposure.
    pub exposure: Exposure,
    /// Radiance of rays that leave the scene.
    pub background: Rgb,
    /// Refuse scenes whose preprocessing would create more elements than this.
    pub max_elements: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 400,
            height: 400,
            pixel_samples: 4,
            element_size: 0.1,
            light_rays: 64,
            bounce_rays: 8,
            gather_rays: 128,
            lrt_depth: 4,
            vrt_depth: 4,
            diffuse_bounces: 0,
            ambient: Rgb::splat(0.0),
            accel: Accel::Bvh,
            direct: DirectLight::Auto,
            shared_faces: false,
            refine: 0,
            refine_contrast: 0.2,
            grid: GridSpec::Auto,
            seed: 1,
            exposure: Exposure::Auto,
            background: Rgb::BLACK,
            max_elements: 20_000_000,
        }
    }
}

/// Spot-light cone: full intensity inside `half_angle_deg`, falling smoothly to zero
/// over a further `falloff_deg`.
#[derive(Clone, Debug, PartialEq)]
pub struct Spot {
    /// Unit axis of the cone.
    pub direction: DVec3,
    /// Half-angle of the fully lit cone, degrees.
    pub half_angle_deg: f64,
    /// Width of the smooth edge, degrees (0 = hard edge).
    pub falloff_deg: f64,
}

/// Largest coordinate a scene may use, in either sign (vertices after their mesh's
/// transform, light positions, the camera). The kernel forms products of three
/// coordinates (edge cross products, squared distances times lengths); docs/NUMERICS.md
/// measures where they overflow (about 1e77), and 1e30 keeps a wide margin.
pub const MAX_COORDINATE: f64 = 1e30;

/// Largest radiometric value a scene may give (a light's intensity in W/sr, the ambient
/// and background radiance, a fixed exposure): far past any real scene, and well inside
/// what flux, radiance and tone mapping can carry without overflowing to infinity.
pub const MAX_RADIOMETRIC: f64 = 1e30;

/// A point light source (paper §3: ideal point lights; spot cones are our extension).
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// Position.
    pub position: DVec3,
    /// Radiant intensity per channel, W/sr.
    pub intensity: Rgb,
    /// Optional cone; `None` is isotropic.
    pub spot: Option<Spot>,
    /// Where it was defined.
    pub loc: SourceLoc,
}

/// Surface material: fractions of incident light per channel that are reflected
/// diffusely, reflected as by a mirror, and transmitted (refracted with `ior`).
/// `diffuse + mirror + transmit <= 1` per channel; the rest is absorbed.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name used by patches.
    pub name: String,
    /// Diffuse reflectance rho_d.
    pub diffuse: Rgb,
    /// Ideal mirror reflectance.
    pub mirror: Rgb,
    /// Dielectric part: split by Fresnel into reflection and refraction.
    pub transmit: Rgb,
    /// Index of refraction of the inside (the side the normal points away from).
    pub ior: f64,
    /// Only the front (the side the patch's normal points to, by its winding) receives
    /// and reflects light: light arriving on the back is absorbed and a viewing ray sees
    /// the back black, so nothing leaks through a thin wall (`sides = 1`). Two-sided
    /// (false) by default; never set for a transmissive material.
    pub one_sided: bool,
    /// Radiance leaving the front of its patches (W m^-2 sr^-1 per channel), the same in
    /// every direction: the patches are area lights (`emit = [r, g, b]`). Black for
    /// a material that emits nothing (the default). Only the front emits.
    pub emit: Rgb,
    /// Where it was defined.
    pub loc: SourceLoc,
}

impl Material {
    /// True when its patches emit light (area lights).
    pub fn is_emitter(&self) -> bool {
        !self.emit.is_black()
    }
    /// True when the material has an ideal-mirror part.
    pub fn is_mirror(&self) -> bool {
        !self.mirror.is_black()
    }
    /// True when the material has a transmissive (dielectric) part.
    pub fn is_transmissive(&self) -> bool {
        !self.transmit.is_black()
    }
    /// True when the material has a specular part of either kind.
    pub fn is_specular(&self) -> bool {
        self.is_mirror() || self.is_transmissive()
    }
    /// True when its patches keep the light arriving on their backs apart from the light
    /// on their fronts, in back elements of their own: a two-sided material that shows
    /// received light (a diffuse part) and emits none. Light on a thin wall's far side
    /// then stays there; a one-sided material refuses it instead, and a material without
    /// a diffuse part shows no received light at all.
    pub fn has_back_face(&self) -> bool {
        !self.one_sided && !self.diffuse.is_black() && !self.is_emitter()
    }
    /// True when light travelling along `d` onto a surface with geometric normal `n` of
    /// this material arrives on a side that takes no light (the back of a one-sided one).
    pub fn refuses(&self, d: glam::DVec3, n: glam::DVec3) -> bool {
        self.one_sided && d.dot(n) > 0.0
    }
}

/// A triangle patch after transforms. Its normal follows the winding
/// (counter-clockwise seen from the front).
#[derive(Clone, Debug, PartialEq)]
pub struct PatchDef {
    /// Corner positions.
    pub vertices: [DVec3; 3],
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Fixed subdivision count n (n*n elements), overriding `element_size`.
    pub subdivisions: Option<u32>,
    /// Length to divide by `element_size` instead of this triangle's longest edge: the
    /// two halves of a quad carry the quad's longest edge (diagonal included), so that
    /// they subdivide identically and weld without a seam whatever the element size.
    pub size_hint: Option<f64>,
    /// Unit shading normals at the corners (from a mesh file's vertex normals or made
    /// behind its crease angle), each on the front side of the patch's plane; `None`
    /// shades the patch flat. They bend shading and specular directions only: the
    /// geometric normal keeps deciding sides and ray offsets.
    pub normals: Option<[DVec3; 3]>,
    /// Texture coordinates at the corners (OBJ `vt`), for `texture`.
    pub uv: Option<[glam::DVec2; 3]>,
    /// Index into `Scene::textures` of the texture multiplying this patch's diffuse
    /// reflectance (its material's `map_Kd`); used only with `uv`.
    pub texture: Option<u32>,
    /// Where it was defined (the `[[quad]]`, `[[triangle]]` or `[[mesh]]` entry).
    pub loc: SourceLoc,
}

/// A complete, validated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Label of the scene (file name).
    pub name: String,
    /// The camera.
    pub camera: Camera,
    /// Render settings.
    pub settings: RenderSettings,
    /// Point lights.
    pub lights: Vec<Light>,
    /// Materials, referenced by index.
    pub materials: Vec<Material>,
    /// Triangle patches.
    pub patches: Vec<PatchDef>,
    /// Diffuse textures, referenced by index from patches.
    pub textures: Vec<super::texture::Texture>,
}
