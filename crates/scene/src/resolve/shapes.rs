//! Shapes: meshes, spheres, quads, boxes and instances, flattened into world space.

use super::*;

impl Ctx<'_> {
    pub(super) fn material_ref(&mut self, path: &str, name: &str, env: &ShapeEnv) -> u32 {
        match env.materials.get(name) {
            Some(&i) => i,
            None => {
                let known: Vec<&str> = env.materials.keys().map(String::as_str).collect();
                self.problem(
                    format!("{path}.material"),
                    format!(
                        "unknown material \"{name}\"; expected one of the scene's materials: {}",
                        known.join(", ")
                    ),
                );
                0
            }
        }
    }

    pub(super) fn shapes(
        &mut self,
        list: &[Tagged],
        base: &str,
        parent: Affine3A,
        env: &ShapeEnv,
        stack: &mut Vec<String>,
        out: &mut Shapes,
    ) {
        for (i, t) in list.iter().enumerate() {
            let path = format!("{base}[{i}]");
            match t.kind.as_str() {
                "mesh" => {
                    let Some(s) = self.body::<MeshShape>(&path, t) else {
                        continue;
                    };
                    let Some(material) = &s.material else {
                        // The file's own materials (an OBJ's MTL library).
                        self.mtl_mesh(&path, parent, &s, out);
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        material,
                        s.emission.as_ref(),
                        env,
                    );
                    let Some(raw) = self.mesh_file(&format!("{path}.file"), &s.file) else {
                        continue;
                    };
                    let geometry = Geometry {
                        positions: &raw.positions,
                        normals: if s.smooth_normals {
                            raw.normals.as_deref()
                        } else {
                            None
                        },
                        uvs: None,
                        uvs1: None,
                        tangents: None,
                        triangles: &raw.triangles,
                    };
                    self.push_mesh(
                        &path,
                        format!("{path} ({})", s.file),
                        geometry,
                        surface,
                        out,
                    );
                }
                "quad" => {
                    let Some(s) = self.body::<QuadShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let o = self.finite3(&format!("{path}.origin"), s.origin);
                    let u = self.finite3(&format!("{path}.edge_u"), s.edge_u);
                    let v = self.finite3(&format!("{path}.edge_v"), s.edge_v);
                    if u.cross(v).length_squared() == 0.0 {
                        self.problem(
                            format!("{path}.edge_v"),
                            "expected two edges that are not parallel and not zero",
                        );
                    }
                    let positions = [o, o + u, o + u + v, o + v];
                    let geometry = Geometry {
                        positions: &positions,
                        normals: None,
                        uvs1: None,
                        uvs: Some(&[
                            glam::Vec2::new(0.0, 0.0),
                            glam::Vec2::new(1.0, 0.0),
                            glam::Vec2::new(1.0, 1.0),
                            glam::Vec2::new(0.0, 1.0),
                        ]),
                        tangents: None,
                        triangles: &[[0, 1, 2], [0, 2, 3]],
                    };
                    self.push_mesh(&path, path.clone(), geometry, surface, out);
                }
                "box" => {
                    let Some(s) = self.body::<BoxShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let lo = self.finite3(&format!("{path}.min"), s.min);
                    let hi = self.finite3(&format!("{path}.max"), s.max);
                    if !lo.cmplt(hi).all() {
                        self.problem(
                            format!("{path}.max"),
                            format!("expected max > min on every axis, got min {lo} and max {hi}"),
                        );
                    }
                    let (positions, triangles) = box_mesh(lo, hi);
                    let geometry = Geometry {
                        positions: &positions,
                        normals: None,
                        uvs: None,
                        uvs1: None,
                        tangents: None,
                        triangles: &triangles,
                    };
                    self.push_mesh(&path, path.clone(), geometry, surface, out);
                }
                "sphere" => {
                    let Some(s) = self.body::<SphereShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let m = surface.to_world;
                    let center = self.finite3(&format!("{path}.center"), s.center);
                    let radius = self.positive(&format!("{path}.radius"), s.radius);
                    let Some(scale) = transform::uniform_scale(&m) else {
                        self.problem(format!("{path}.transform"), "expected rotations, translations and uniform scales only: a sphere cannot be squashed");
                        continue;
                    };
                    let radius = radius * scale;
                    let area_m2 =
                        4.0 * std::f64::consts::PI * (radius as f64 * out.metres_per_unit).powi(2);
                    let emission = surface
                        .emission
                        .and_then(|e| self.emission(&format!("{path}.emission"), e, area_m2));
                    out.spheres.push(SphereDesc {
                        origin: path.clone(),
                        center: m.transform_point3(center),
                        radius,
                        material: surface.material,
                        emission,
                    });
                }
                "instance" => {
                    let Some(s) = self.body::<InstanceShape>(&path, t) else {
                        continue;
                    };
                    let m = parent * self.transform(&path, &s.transform);
                    let Some(shapes) = env.objects.get(&s.object) else {
                        let known: Vec<&str> = env.objects.keys().map(String::as_str).collect();
                        self.problem(
                            format!("{path}.object"),
                            format!(
                                "unknown object \"{}\"; expected one of the scene's objects: {}",
                                s.object,
                                known.join(", ")
                            ),
                        );
                        continue;
                    };
                    if stack.contains(&s.object) || stack.len() >= MAX_INSTANCE_DEPTH {
                        self.problem(format!("{path}.object"), format!("object \"{}\" instances itself (directly or through others); expected a hierarchy without cycles, at most {MAX_INSTANCE_DEPTH} deep", s.object));
                        continue;
                    }
                    stack.push(s.object.clone());
                    self.shapes(shapes, &format!("objects.{}", s.object), m, env, stack, out);
                    stack.pop();
                }
                "gltf" => self.gltf_shape(&path, t, parent, out),
                other => self.unknown_type(
                    &path,
                    "shape",
                    other,
                    &["mesh", "quad", "box", "sphere", "instance", "gltf"],
                ),
            }
        }
    }

    /// Reads the file `file`, named at `path`, once per scene: `load` reads it (reporting its
    /// own problems), `cache` is the table that keeps it (`None` for a file that failed).
    pub(super) fn load_once<T>(
        &mut self,
        path: &str,
        file: &str,
        cache: fn(&mut Self) -> &mut HashMap<PathBuf, Option<Arc<T>>>,
        load: impl FnOnce(&mut Self, &Path) -> Option<T>,
    ) -> Option<Arc<T>> {
        let rel = match confine(file) {
            Ok(rel) => rel,
            Err(msg) => {
                self.problem(path, msg);
                return None;
            }
        };
        if let Some(cached) = cache(self).get(&rel) {
            return cached.clone();
        }
        let loaded = load(self, &rel).map(Arc::new);
        cache(self).insert(rel, loaded.clone());
        loaded
    }

    /// Loads (once) the mesh file named at `path`.
    pub(super) fn mesh_file(&mut self, path: &str, file: &str) -> Option<Arc<RawMesh>> {
        self.load_once(
            path,
            file,
            |c| &mut c.meshes,
            |ctx, rel| {
                let shown = ctx.source.display_path(rel);
                match ctx.source.read(rel) {
                    Err(e) => {
                        ctx.problem(
                            path,
                            format!("cannot read mesh file {}: {e}", shown.display()),
                        );
                        None
                    }
                    Ok(bytes) => {
                        let ext = rel
                            .extension()
                            .map(|e| e.to_string_lossy().into_owned())
                            .unwrap_or_default();
                        // Files the mesh names (an OBJ's material libraries), beside it.
                        let dir = rel.parent().unwrap_or(Path::new("")).to_path_buf();
                        let source = ctx.source;
                        let side = |name: &str| {
                            let joined = dir.join(name);
                            let rel = crate::source::confine(&joined.to_string_lossy())?;
                            source.read(&rel).map_err(|e| e.to_string())
                        };
                        match mesh::parse(&bytes, &ext, &side) {
                            Ok(m) => {
                                for w in &m.warnings {
                                    ctx.warnings.push(format!("{}: {w}", shown.display()));
                                }
                                Some(m)
                            }
                            Err(e) => {
                                ctx.problems.push(Problem {
                                    file: shown,
                                    path: e.location,
                                    message: format!("{} (referenced by {path})", e.message),
                                });
                                None
                            }
                        }
                    }
                }
            },
        )
    }

    /// The transform, material and emission every surface shape has.
    pub(super) fn surface<'e>(
        &mut self,
        path: &str,
        parent: Affine3A,
        steps: &[TransformStep],
        material: &str,
        emission: Option<&'e EmissionFile>,
        env: &ShapeEnv,
    ) -> Surface<'e> {
        Surface {
            to_world: parent * self.transform(path, steps),
            material: self.material_ref(path, material, env),
            emission,
        }
    }

    /// Adds a triangle mesh given in its own coordinates.
    pub(super) fn push_mesh(
        &mut self,
        path: &str,
        origin: String,
        g: Geometry,
        surface: Surface,
        out: &mut Shapes,
    ) {
        let m = surface.to_world;
        let nm = transform::normal_matrix(&m);
        let mirrored = m.matrix3.determinant() < 0.0;
        let mesh = MeshDesc {
            origin,
            positions: g.positions.iter().map(|&p| m.transform_point3(p)).collect(),
            normals: g.normals.map(|ns| {
                ns.iter()
                    .map(|&n| Vec3::from(nm * glam::Vec3A::from(n)).normalize_or_zero())
                    .collect()
            }),
            uvs: g.uvs.map(<[glam::Vec2]>::to_vec),
            uvs1: g.uvs1.map(<[glam::Vec2]>::to_vec),
            // Tangents turn with the shape (a mirroring transform flips the bitangent and,
            // below, the winding).
            tangents: g.tangents.map(|t| {
                t.iter()
                    .map(|c| {
                        let c = c.map(|v| {
                            let d = m.transform_vector3(v.truncate()).normalize_or_zero();
                            d.extend(if mirrored { -v.w } else { v.w })
                        });
                        if mirrored { [c[0], c[2], c[1]] } else { c }
                    })
                    .collect()
            }),
            // A mirroring transform flips the winding; swap it back so the front face stays
            // on the side the (transformed) normals point to.
            triangles: g
                .triangles
                .iter()
                .map(|&[a, b, c]| if mirrored { [a, c, b] } else { [a, b, c] })
                .collect(),
            material: surface.material,
            emission: None,
        };
        let emission = surface.emission.and_then(|e| {
            let area_m2 = mesh.area() * out.metres_per_unit * out.metres_per_unit;
            self.emission(&format!("{path}.emission"), e, area_m2)
        });
        out.meshes.push(MeshDesc { emission, ..mesh });
    }
}

pub(super) struct ShapeEnv<'a> {
    pub(super) materials: &'a BTreeMap<String, u32>,
    pub(super) objects: &'a BTreeMap<String, Vec<Tagged>>,
}

/// A shape's placement, material and emission, resolved.
pub(super) struct Surface<'e> {
    pub(super) to_world: Affine3A,
    pub(super) material: u32,
    pub(super) emission: Option<&'e EmissionFile>,
}

/// A triangle mesh in its own coordinates.
pub(super) struct Geometry<'g> {
    pub(super) positions: &'g [Vec3],
    pub(super) normals: Option<&'g [Vec3]>,
    pub(super) uvs: Option<&'g [glam::Vec2]>,
    pub(super) uvs1: Option<&'g [glam::Vec2]>,
    pub(super) tangents: Option<&'g [[glam::Vec4; 3]]>,
    pub(super) triangles: &'g [[u32; 3]],
}

pub(super) struct Shapes {
    pub(super) meshes: Vec<MeshDesc>,
    pub(super) spheres: Vec<SphereDesc>,
    pub(super) metres_per_unit: f64,
    /// Index the first material a shape brings (a glTF file's) will have: after the scene's.
    pub(super) first_material: u32,
    /// Materials brought by shapes, in order.
    pub(super) materials: Vec<MaterialDesc>,
    /// Lights brought by shapes.
    pub(super) lights: Vec<LightDesc>,
}

/// An axis-aligned box as 12 triangles wound so that normals point outwards.
pub fn box_mesh(lo: Vec3, hi: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let corner = |i: u32| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let positions = (0..8).map(corner).collect();
    // Faces as quads (counter-clockwise seen from outside): -x, +x, -y, +y, -z, +z.
    let quads = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (positions, triangles)
}
