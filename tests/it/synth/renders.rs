//! Every sample's image against a render of its recorded inputs, through the library and
//! `matedit render`.

use matedit::io::{self, npy};
use matedit::synth::{self, tar};
use matedit::{Batch, Convention, Device, EnvMap, NormalMap, Renderer, Scene};

use super::{dir, matedit, npy_rgb, small_spec, synth_cmd};

#[test]
fn every_image_is_a_render_of_its_recorded_inputs() {
    let t = dir();
    let spec = small_spec(t.path());
    let out = t.path().join("ds");
    synth_cmd(&spec, &out, &[]).assert().success();
    let cpu = Renderer::new(Device::Cpu).unwrap();
    let mut checked = 0;
    let mut kinds = std::collections::BTreeSet::new();
    for tar_path in synth::data_files(&out).unwrap() {
        if tar_path.extension().is_some_and(|e| e != "tar") {
            continue;
        }
        let members = tar::decode(&std::fs::read(&tar_path).unwrap()).unwrap();
        for sample in members.chunks(6) {
            let get = |suffix: &str| {
                let (n, b) = sample.iter().find(|(n, _)| n.ends_with(suffix)).unwrap();
                (n.clone(), b.clone())
            };
            let key = get("params.json").0.split('.').next().unwrap().to_string();
            let params: serde_json::Value = serde_json::from_slice(&get("params.json").1).unwrap();
            kinds.insert(params["normals_item"].to_string() + &params["material_item"].to_string());
            let (h, w, normals) = npy_rgb(&get("normals.npy").1);
            let (eh, ew, texels) = npy_rgb(&get("env.npy").1);
            let (_, _, image) = npy_rgb(&get("image.npy").1);
            // the mask marks the object: the pixels whose normal is not zero
            let mask = npy::parse(&get("mask.npy").1).unwrap();
            assert_eq!(mask.shape, [h, w]);
            for (m, n) in mask.data.iter().zip(&normals) {
                assert_eq!(*m == 1.0, *n != [0.0; 3]);
            }
            let sample_dir = t.path().join(&key);
            std::fs::create_dir_all(&sample_dir).unwrap();
            let mat_path = sample_dir.join("material.json");
            std::fs::write(&mat_path, get("material.json").1).unwrap();
            let scene = Scene {
                normals: NormalMap::new(w, h, normals).unwrap(),
                env: EnvMap::new(eh, ew, Convention::Equirect, texels).unwrap(),
                material: io::load_material(&mat_path).unwrap(),
                camera: matedit::Camera::Orthographic,
            };
            let again = cpu
                .render(&Batch::single(scene).unwrap())
                .unwrap()
                .remove(0);
            assert!(
                again.pixels == image,
                "sample {key}: the library renders other bits"
            );

            // and `matedit render` of the recorded files
            for m in ["normals.npy", "env.npy"] {
                std::fs::write(sample_dir.join(m), get(m).1).unwrap();
            }
            let render_out = sample_dir.join("render.npy");
            matedit()
                .args(["render", "--device", "cpu", "--env-size", "full", "-o"])
                .arg(&render_out)
                .arg("--normals")
                .arg(sample_dir.join("normals.npy"))
                .arg("--env")
                .arg(sample_dir.join("env.npy"))
                .arg("--material")
                .arg(&mat_path)
                .assert()
                .success();
            let (_, _, rendered) = npy_rgb(&std::fs::read(&render_out).unwrap());
            assert!(
                rendered == image,
                "sample {key}: `matedit render` gives other bits"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 12);
    assert!(kinds.len() > 4, "too few kinds of sample drawn: {kinds:?}");
}
