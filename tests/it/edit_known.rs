//! `matedit edit` given what is known of a photo: its object's normals and its light
//! (`--normals`, `--env`, `PhotoOptions::{normals, env}`) take the nets' place, and bad
//! files are refused in one line.

use crate::edit_photo::{edit, report};
use crate::photos::{photo, red_blob, true_normals};

use matedit::io;
use matedit::{Convention, Device, Renderer};

/// The photo of [`photo`]'s blob with its true normals and light given: they take the
/// nets' place (the light neither matched to the background, refined nor blurred, the
/// level "given"), and with them the refined material re-renders the photo far better than
/// from the nets' guesses (34 against 16 dB when written).
#[test]
fn known_normals_and_light_take_the_nets_place() {
    use matedit::edit::photo::light::LevelFrom;
    use matedit::edit::photo::{self, PhotoOptions};
    let tmp = tempfile::tempdir().unwrap();
    let (img, mask) = red_blob(tmp.path());
    let (normals, _) = true_normals("blobby:seed=3", (96, 96));
    // the light at twice the nets' size: brought down to theirs
    let env = matedit::builtin_sky::procedural_env(32, 64, Convention::Equirect);
    let renderer = Renderer::new(Device::Cpu).unwrap();
    let nets = matedit::nets::Nets::builtin().unwrap();
    let decompose = |options: &PhotoOptions| {
        photo::decompose(
            &renderer,
            &nets,
            &img,
            Some(mask.as_slice()),
            options,
            &mut |_| {},
        )
        .unwrap()
    };
    let guessed = decompose(&PhotoOptions::default());
    let known = decompose(&PhotoOptions {
        normals: Some(normals.clone()),
        env: Some(env.clone()),
        // only the material moves, and 20 steps do not bring it from the nets' guess
        steps: 200,
        ..PhotoOptions::default()
    });
    assert_eq!(known.light_factors.from, LevelFrom::Given);
    let small = matedit::io::resample::downsample(&env, 16, 32).unwrap();
    assert_eq!(known.predicted_env, small);
    // neither refined nor blurred
    assert_eq!(known.env, small);
    let c = known.crop;
    let mut on = 0;
    for (i, n) in known.normals.normals.iter().enumerate() {
        let (x, y) = (c.x0 + (i % c.size) as i64, c.y0 + (i / c.size) as i64);
        if !(0..96).contains(&x) || !(0..96).contains(&y) {
            continue;
        }
        let (x, y) = (x as usize, y as usize);
        if mask[y * 96 + x] {
            assert_eq!(*n, normals.normals[y * 96 + x], "pixel {x}, {y}");
            on += 1;
        }
    }
    assert_eq!(on, mask.iter().filter(|&&m| m).count());
    eprintln!(
        "I' refined: {:.2} dB from the nets, {:.2} dB known",
        guessed.psnr_refined, known.psnr_refined
    );
    assert!(known.psnr_refined > 30.0, "{}", known.psnr_refined);
    assert!(known.psnr_refined > guessed.psnr_refined + 3.0);
}

/// `--normals`, `--env`, `--like-env` and `--like-steps` on the command line: taken (the
/// report says which light was given and how many steps each read took), and refused in one line, exit 2, nothing written, when the normal map is not the
/// photo's size or the nets' light size does not divide the map.
#[test]
fn known_normals_and_light_from_files() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, a_mask) = photo(tmp.path(), "a", "capsule:seed=1", "plastic-red", 48);
    let normals = tmp.path().join("normals.npy");
    let up = vec![[0.0f32, 0.0, 1.0]; 48 * 48];
    std::fs::write(&normals, io::npy::encode_rgb(48, 48, &up)).unwrap();
    let small = tmp.path().join("small.npy");
    std::fs::write(&small, io::npy::encode_rgb(40, 48, &up[..40 * 48])).unwrap();
    let light = tmp.path().join("light.exr");
    let env = matedit::builtin_sky::procedural_env(16, 32, Convention::Equirect);
    std::fs::write(&light, io::exr::encode_rgb(32, 16, &env.texels).unwrap()).unwrap();
    let odd = tmp.path().join("odd.exr");
    std::fs::write(
        &odd,
        io::exr::encode_rgb(30, 15, &env.texels[..450]).unwrap(),
    )
    .unwrap();
    let out = tmp.path().join("out");
    let base = [
        a.as_os_str(),
        "--mask".as_ref(),
        a_mask.as_os_str(),
        "--material".as_ref(),
        "gold".as_ref(),
        "--steps".as_ref(),
        "2".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ];
    let with = |extra: &[&std::ffi::OsStr]| {
        let mut all = base.to_vec();
        all.extend_from_slice(extra);
        edit(&all)
    };
    for (extra, want) in [
        (
            ["--normals".as_ref(), small.as_os_str()],
            "normal map is 40x48",
        ),
        (["--env".as_ref(), odd.as_os_str()], "odd.exr"),
    ] {
        let o = with(&extra).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{want}: {err}");
        assert!(err.contains(want), "{want}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists(), "{want}: wrote {}", out.display());
    }
    with(&[
        "--normals".as_ref(),
        normals.as_os_str(),
        "--env".as_ref(),
        light.as_os_str(),
    ])
    .assert()
    .success();
    let r = report(&out);
    assert_eq!(r["light_level_from"], "given");
    assert_eq!(r["like_light_level_from"], serde_json::Value::Null);
    // the other photo's light: --like-env (here the photo itself stands for the other)
    let other = tmp.path().join("other");
    let mut all = base[..3].to_vec();
    all.extend([
        "--like".as_ref(),
        a.as_os_str(),
        "--like-mask".as_ref(),
        a_mask.as_os_str(),
        "--like-env".as_ref(),
        light.as_os_str(),
        "--steps".as_ref(),
        "2".as_ref(),
        "--like-steps".as_ref(),
        "3".as_ref(),
        "-o".as_ref(),
        other.as_os_str(),
    ]);
    edit(&all).assert().success();
    let r = report(&other);
    assert_eq!(r["light_level_from"], "background");
    assert_eq!(r["like_light_level_from"], "given");
    // --like-steps: the other photo's read takes its own steps
    assert_eq!(
        (r["steps"].as_u64(), r["like_steps"].as_u64()),
        (Some(2), Some(3))
    );
}

/// The other photo's options (`--like-mask`, `--like-env`, `--like-steps`) with `--material`
/// in place of `--like` are refused, exit 2, nothing written: clap waives an argument's
/// requirement of `--like` when `--like` conflicts with an argument given, so each says
/// it conflicts with `--material` as well.
#[test]
fn the_other_photos_options_need_the_other_photo() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, a_mask) = photo(tmp.path(), "a", "capsule:seed=1", "plastic-red", 48);
    let out = tmp.path().join("out");
    for (option, value) in [
        ("--like-mask", a_mask.as_os_str()),
        ("--like-env", "light.exr".as_ref()),
        ("--like-steps", "3".as_ref()),
    ] {
        let o = edit(&[
            a.as_os_str(),
            "--mask".as_ref(),
            a_mask.as_os_str(),
            "--material".as_ref(),
            "gold".as_ref(),
            option.as_ref(),
            value,
            "-o".as_ref(),
            out.as_os_str(),
        ])
        .output()
        .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{option}: {err}");
        assert!(
            err.contains(option) && err.contains("--material"),
            "{option}: {err}"
        );
        assert!(!out.exists(), "{option}: wrote {}", out.display());
    }
}
