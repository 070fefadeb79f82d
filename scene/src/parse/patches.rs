//! The patches of a scene's `[[triangle]]`, `[[quad]]` and `[[mesh]]` entries, in the
//! order they appear in the file, with the materials their mesh files bring.

use super::*;

/// Builds triangle patches and registers MTL materials as meshes are read.
pub(super) struct PatchBuilder<'c, 'a> {
    pub(super) cx: &'c Ctx<'a>,
    pub(super) materials: MaterialTable,
    pub(super) patches: Vec<PatchDef>,
}

impl PatchBuilder<'_, '_> {
    fn material_ref(&self, m: &Spanned<String>, field: &str) -> Result<u32, SceneError> {
        self.materials
            .toml
            .get(m.get_ref())
            .copied()
            .ok_or_else(|| self.cx.err(m, field, format!("material '{}' is not defined", m.get_ref())))
    }

    fn subdivisions(&self, v: &Option<Spanned<i64>>, field: &str) -> Result<Option<u32>, SceneError> {
        v.as_ref().map(|v| self.cx.int_in(v, field, 1, MAX_SUBDIVISIONS).map(|n| n as u32)).transpose()
    }

    /// The corners of a `[[triangle]]`/`[[quad]]`, exactly `N` points.
    fn corners<const N: usize>(&self, p: &RawPolygon, field: &str) -> Result<[DVec3; N], SceneError> {
        let pts = p.vertices.get_ref();
        if pts.len() != N {
            return Err(self.cx.err(&p.vertices, field, format!("expected {N} vertices, found {}", pts.len())));
        }
        let mut out = [DVec3::ZERO; N];
        for (k, (o, v)) in out.iter_mut().zip(pts).enumerate() {
            let [x, y, z] = v.as_slice() else {
                return Err(self.cx.err(
                    &p.vertices,
                    field,
                    format!("vertex {k} has {} coordinates, expected 3", v.len()),
                ));
            };
            *o = DVec3::new(*x, *y, *z);
            if !o.is_finite() {
                return Err(self.cx.err(&p.vertices, field, format!("vertex {k} = {:?} is not finite", v)));
            }
            if o.abs().max_element() > MAX_COORDINATE {
                let msg = format!("vertex {k} = {v:?} is out of range [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}]");
                return Err(self.cx.err(&p.vertices, field, msg));
            }
        }
        Ok(out)
    }

    pub(super) fn triangle(&mut self, i: usize, t: &RawPolygon) -> Result<(), SceneError> {
        let field = format!("triangle[{i}].vertices");
        let v: [DVec3; 3] = self.corners(t, &field)?;
        if is_degenerate(&v) {
            return Err(self.cx.err(&t.vertices, field, format!("triangle[{i}] is degenerate (zero area)")));
        }
        let material = self.material_ref(&t.material, &format!("triangle[{i}].material"))?;
        let subdivisions = self.subdivisions(&t.subdivisions, &format!("triangle[{i}].subdivisions"))?;
        self.patches.push(PatchDef {
            vertices: v,
            material,
            subdivisions,
            size_hint: None,
            normals: None,
            uv: None,
            texture: None,
            loc: self.cx.loc(&t.vertices),
        });
        Ok(())
    }

    pub(super) fn quad(&mut self, i: usize, q: &RawPolygon) -> Result<(), SceneError> {
        let field = format!("quad[{i}].vertices");
        let v: [DVec3; 4] = self.corners(q, &field)?;
        check_quad(&v).map_err(|why| self.cx.err(&q.vertices, &field, format!("quad[{i}] {why}")))?;
        let material = self.material_ref(&q.material, &format!("quad[{i}].material"))?;
        let subdivisions = self.subdivisions(&q.subdivisions, &format!("quad[{i}].subdivisions"))?;
        // Without a fixed n, both halves are subdivided from the longest edge of the quad
        // including the shared diagonal (at preprocessing, with the element size then in
        // force), so that they subdivide identically and weld without seams.
        let longest = [v[1] - v[0], v[2] - v[1], v[3] - v[2], v[0] - v[3], v[2] - v[0]]
            .iter()
            .map(|e| e.length())
            .fold(0.0, f64::max);
        let size_hint = Some(longest);
        let loc = self.cx.loc(&q.vertices);
        for tri in [[v[0], v[1], v[2]], [v[0], v[2], v[3]]] {
            self.patches.push(PatchDef {
                vertices: tri,
                material,
                subdivisions,
                size_hint,
                normals: None,
                uv: None,
                texture: None,
                loc: loc.clone(),
            });
        }
        Ok(())
    }

    pub(super) fn mesh(
        &mut self,
        i: usize,
        spanned: &Spanned<RawMesh>,
        base_dir: &Path,
        read: ReadFile<'_>,
    ) -> Result<(), SceneError> {
        let cx = self.cx;
        let m = spanned.get_ref();
        let f = |name: &str| format!("mesh[{i}].{name}");
        let (path, key) = match (&m.file, &m.obj) {
            (Some(p), None) => (p, "file"),
            (None, Some(p)) => (p, "obj"),
            (Some(_), Some(o)) => {
                return Err(cx.err(o, f("obj"), "`obj` is another name of `file`: give only one of them"));
            }
            (None, None) => return Err(cx.err(spanned, format!("mesh[{i}]"), "a [[mesh]] needs `file = PATH`")),
        };
        let translate = m.translate.as_ref().map(|v| cx.vec3(v, &f("translate"))).transpose()?.unwrap_or(DVec3::ZERO);
        let rotate = m.rotate.as_ref().map(|v| cx.vec3(v, &f("rotate"))).transpose()?.unwrap_or(DVec3::ZERO);
        let scale = match &m.scale {
            Some(v) => self.scale(v, &f("scale"))?,
            None => DVec3::new(1.0, 1.0, 1.0),
        };
        let subdivisions = self.subdivisions(&m.subdivisions, &f("subdivisions"))?;
        let material = m.material.as_ref().map(|s| self.material_ref(s, &f("material"))).transpose()?;
        let crease =
            m.crease_angle.as_ref().map(|a| cx.float_in(a, &f("crease_angle"), 0.0, false, 180.0)).transpose()?;
        let shading = MeshShading {
            file_normals: m.normals.as_ref().is_none_or(|b| *b.get_ref()),
            crease_cos: crease.map(|deg| deg.to_radians().cos()),
        };
        let entry = MeshEntry {
            file: path.get_ref(),
            key,
            at: cx.loc(path),
            field: format!("mesh[{i}]"),
            transform: Transform::new(scale, rotate, translate),
            material,
            shading,
        };
        // The mesh's triangles become patches as they are read, a run at a time.
        let patches = &mut self.patches;
        let first = patches.len();
        let read = stream_mesh(&entry, base_dir, read, &mut self.materials, &mut |run| {
            patches.extend(run.into_iter().map(|t| PatchDef {
                vertices: t.v,
                material: t.material,
                subdivisions,
                size_hint: None,
                normals: t.normals,
                uv: t.uv,
                texture: t.texture,
                loc: entry.at.clone(),
            }));
        });
        if read.is_err() {
            patches.truncate(first);
        }
        read
    }

    fn scale(&self, v: &Spanned<toml::Value>, field: &str) -> Result<DVec3, SceneError> {
        let num = |x: &toml::Value| match x {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(f) => Some(*f),
            _ => None,
        };
        let s = match v.get_ref() {
            toml::Value::Array(a) if a.len() == 3 => {
                let c: Vec<f64> = a.iter().filter_map(num).collect();
                match c.as_slice() {
                    [x, y, z] => DVec3::new(*x, *y, *z),
                    _ => return Err(self.cx.err(v, field, "expected a number or [sx, sy, sz]")),
                }
            }
            other => match num(other) {
                Some(x) => DVec3::new(x, x, x),
                None => return Err(self.cx.err(v, field, format!("expected a number or [sx, sy, sz], found {other}"))),
            },
        };
        for (c, name) in s.to_array().iter().zip(XYZ_NAMES) {
            if !c.is_finite() || *c == 0.0 {
                return Err(self.cx.err(v, field, format!("{name} = {c} is not a finite non-zero number")));
            }
        }
        Ok(s)
    }
}
