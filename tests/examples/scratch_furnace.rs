use ember_cli::LoadedScene;
use ember_kernel::integrator::{li, Integrator};
use ember_kernel::sampler::{IndependentSampler, Sampler};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = LoadedScene::load(Path::new(&args[1])).unwrap();
    let (x, y): (u32, u32) = (args[2].parse().unwrap(), args[3].parse().unwrap());
    let n: u32 = args[4].parse().unwrap();
    let (_, path, _) = scene.path_settings().unwrap();
    let cam = scene.camera(24, 18);
    let view = scene.data.view();
    for integ in [
        Integrator::PathImplicit,
        Integrator::PathExplicit,
        Integrator::PathMis,
    ] {
        let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for i in 0..n {
            let mut s = IndependentSampler::new(7, (y * 24 + x) as u64, i);
            let ray = cam.generate_ray(x, y, s.next_2d());
            let l = li(integ, &view, &ray, &path, &mut s).as_dvec3();
            sum += l;
            sum2 += l * l;
        }
        let m = sum / n as f64;
        let se = ((sum2 / n as f64 - m * m) / n as f64).map(f64::sqrt);
        println!("{integ:?}: {m:.5} +- {se:.5}");
    }
}
