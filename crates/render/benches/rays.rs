//! Ray casting throughput: closest-hit and occlusion queries on the Cornell box, and on a
//! generated height field of 2 M triangles with near-vertical rays from random origins (the
//! incoherent, memory-bound case of BENCHMARKS.md, where Embree 4 casts 1.17 Mrays/s and plain
//! obvhs 0.71 Mrays/s on one core). One thread; throughput is printed as rays/s.
//!
//!     cargo bench -p tessera-render --bench rays

use std::path::Path;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Vec2, Vec3A};
use tessera_render::geometry::Accel;
use tessera_render::ray::Ray;
use tessera_render::sampler::hash::{mix64, u32_to_unit};
use tessera_render::sampling::square_to_uniform_sphere;

fn unit2(i: u64) -> Vec2 {
    let h = mix64(i ^ 0xbe7c);
    Vec2::new(u32_to_unit(h as u32), u32_to_unit((h >> 32) as u32))
}

fn cornell() -> (Accel, Vec<Ray>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.json");
    let desc = tessera_scene::load(&path).expect("cornell box scene");
    let tris: Vec<[Vec3A; 3]> = desc
        .meshes
        .iter()
        .flat_map(|m| {
            m.triangles
                .iter()
                .map(|t| t.map(|i| Vec3A::from(m.positions[i as usize])))
        })
        .collect();
    // Rays from random points inside the box in uniformly random directions: the rays a path
    // tracer casts there.
    let rays = (0..1 << 20)
        .map(|i| {
            let a = unit2(2 * i);
            let b = unit2(2 * i + 1);
            let o = Vec3A::new(a.x * 550.0, a.y * 548.0, b.x * 559.0);
            Ray::new(
                o,
                square_to_uniform_sphere(Vec2::new(b.y, u32_to_unit(mix64(i) as u32))),
            )
        })
        .collect();
    (Accel::build(&tris, &[]), rays)
}

/// A 1000 × 1000 grid height field: 2 M triangles over [0, 1000]², heights up to 50.
fn height_field() -> (Accel, Vec<Ray>) {
    let n = 1000usize;
    let h = |x: usize, z: usize| {
        let (x, z) = (x as f32, z as f32);
        20.0 * (x * 0.05).sin() * (z * 0.043).cos() + 10.0 * (x * 0.31 + z * 0.17).sin() + 25.0
    };
    let v = |x: usize, z: usize| Vec3A::new(x as f32, h(x, z), z as f32);
    let mut tris = Vec::with_capacity(2 * n * n);
    for z in 0..n {
        for x in 0..n {
            tris.push([v(x, z), v(x + 1, z), v(x + 1, z + 1)]);
            tris.push([v(x, z), v(x + 1, z + 1), v(x, z + 1)]);
        }
    }
    let start = Instant::now();
    let accel = Accel::build(&tris, &[]);
    eprintln!(
        "height field: {} triangles, BVH built in {:.2} s",
        tris.len(),
        start.elapsed().as_secs_f64()
    );
    let rays = (0..1 << 20)
        .map(|i| {
            let a = unit2(2 * i);
            let b = unit2(2 * i + 1);
            let o = Vec3A::new(a.x * 1000.0, 100.0, a.y * 1000.0);
            let d = Vec3A::new((b.x - 0.5) * 0.2, -1.0, (b.y - 0.5) * 0.2).normalize();
            Ray::new(o, d)
        })
        .collect();
    (accel, rays)
}

fn bench(c: &mut Criterion) {
    for (name, (accel, rays)) in [
        ("cornell_box", cornell()),
        ("height_field_2M", height_field()),
    ] {
        let mut group = c.benchmark_group(name);
        group.throughput(Throughput::Elements(rays.len() as u64));
        group.sample_size(10);
        group.bench_function("closest_hit", |b| {
            b.iter(|| {
                rays.iter()
                    .filter(|r| accel.intersect(r, f32::INFINITY).is_some())
                    .count()
            })
        });
        group.bench_function("occlusion", |b| {
            b.iter(|| rays.iter().filter(|r| accel.occluded(r, 1e30)).count())
        });
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
