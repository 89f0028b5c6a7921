//! `matedit edit`: the object in a photo made of another material (library:
//! `matedit::edit::photo`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use matedit::edit::photo::light::LevelFrom;
use matedit::edit::photo::{self, Object, PhotoOptions};
use matedit::io::{self, Format};
use matedit::nets::Nets;
use matedit::{Accuracy, Convention, Device, Image, Material, NormalMap, Renderer};
use serde_json::json;

use super::shared::{Failure, PointingArgs, pointing_json};

mod outputs;
use outputs::encode_outputs;

/// Shown after the options by `matedit help edit`.
pub const EXAMPLES: &str = "\
Examples:
  matedit edit photo.jpg --material gold -o out/            (a preset: `matedit presets`)
  matedit edit photo.png --material brass.json -o out/ --mask object.png
  matedit edit photo.jpg --material gold -o out/ --box 120,80,410,360
  matedit edit photo.jpg --material gold -o out/ --point 250,200 --not 260,330
  matedit edit photo.exr --like other.jpg -o out/          (the other photo's material)
  matedit edit photo.exr --material gold -o out/ --mask m.png --env probe.exr --normals n.npy
                                                           (a light and normals you measured)

Writes OUT_DIR/edit.(png|jpg|exr) (the input's kind), normals.png, mask.png, light.exr
(the light the edit renders under: the refined light blurred, or --env's), material.json, sphere.png
(the refined material on a sphere under the built-in sky), compare.png (photo | edit |
normals | sphere) and report.json (stage times, PSNR of the re-rendered photo before and
after refinement). A PNG's alpha is its mask unless --mask,
--box or --point is given; without any, the nets find the object, and when no single
object stands out (they take the table or the wall for it) the edit is refused: point at
it. --box cuts the object out of the box (nothing outside it is kept), --point marks
pixels on it and --not pixels off it: a cut that follows the photo's colours and edges,
with the nets' mask for a prior (docs/edit.md).";

/// The options of `matedit edit`.
#[derive(clap::Args)]
pub struct Args {
    /// The photo: JPEG or PNG (sRGB), EXR or NPY (linear).
    #[arg(value_name = "PHOTO")]
    photo: PathBuf,
    /// The new material: a preset name or a material .json file.
    #[arg(
        long,
        value_name = "PRESET|FILE",
        required_unless_present = "like",
        conflicts_with = "like"
    )]
    material: Option<String>,
    /// Take the material predicted and refined from another photo.
    #[arg(long, value_name = "OTHER_PHOTO")]
    like: Option<PathBuf>,
    /// The object's mask in the other photo (as --mask; default: its PNG alpha, else the
    /// nets find it).
    #[arg(
        long,
        value_name = "MASK",
        requires = "like",
        conflicts_with = "material"
    )]
    like_mask: Option<PathBuf>,
    /// The other photo's light, known (as --env for the photo): its material is read under it.
    #[arg(
        long,
        value_name = "FILE",
        requires = "like",
        conflicts_with = "material"
    )]
    like_env: Option<PathBuf>,
    /// Refinement steps of the other photo's read [default: as --steps]: more read its
    /// material closer to its own colour, fewer or more than the photo's own pair the two
    /// reads less well (docs/edit.md, "A material read from a photo of a sphere").
    #[arg(long, value_name = "K", requires = "like", conflicts_with = "material")]
    like_steps: Option<usize>,
    /// Output folder (created if missing).
    #[arg(short, long, value_name = "OUT_DIR")]
    output: PathBuf,
    /// The object's mask (PNG, EXR or NPY, the photo's size; a pixel counts above half).
    #[arg(long, value_name = "MASK", conflicts_with_all = ["bounds", "points", "nots"])]
    mask: Option<PathBuf>,
    #[command(flatten)]
    pointing: PointingArgs,
    /// Refinement steps through the layer [default: 20; 100 with both --normals and --env].
    #[arg(long, value_name = "K")]
    steps: Option<usize>,
    /// Refinement steps of the normals after material and light (0: keep the nets' normals).
    #[arg(long, value_name = "J", default_value_t = PhotoOptions::default().normal_steps)]
    normal_steps: usize,
    /// How much of the photo's own detail the edit keeps, 0 to 1: 1 the photo with the
    /// shading changed from its material to the new one (its own material gives it back),
    /// 0 the re-rendered object alone.
    #[arg(long, value_name = "D", default_value_t = PhotoOptions::default().detail, value_parser = parse_detail)]
    detail: f32,
    /// Keep the nets' light level instead of the background's, or on black a grey card's
    /// exposure (docs/edit.md).
    #[arg(long)]
    no_background_light: bool,
    /// The nets' predictions as they are, without refinement.
    #[arg(long, conflicts_with_all = ["steps", "normal_steps", "like_steps"])]
    no_refine: bool,
    /// The object's normals, known, in place of the nets': a normal map as for `render`
    /// (camera frame: x right, y up, z towards the viewer), the photo's size; a pixel on the
    /// object without one takes the nets'.
    #[arg(long, value_name = "FILE")]
    normals: Option<PathBuf>,
    /// The light, known, in place of the nets': a lat-long map (EXR or NPY, the camera's
    /// frame, the photo's linear units) that the nets' light size divides; only the material
    /// is refined, and the edit renders under the light as it is (not blurred).
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// Weights of the nets (default: the ones built in; docs/nets_card.md).
    #[arg(long, value_name = "FILE")]
    weights: Option<PathBuf>,
    /// Run the nets once on the photo only, not also on its mirror image (half their time;
    /// the two answers averaged are closer to the truth, docs/nets.md).
    #[arg(long)]
    no_mirror: bool,
    /// Backend, as for `render`.
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
}

/// Runs `matedit edit`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let t0 = Instant::now();
    let kind = io::format_of(
        &args.photo,
        "the photo",
        &[Format::Jpeg, Format::Png, Format::Exr, Format::Npy],
    )?;
    let (photo, alpha_mask) = load_photo(&args.photo)?;
    let pointing = args.pointing.pointing(None, photo.width, photo.height)?;
    let mask = match &args.mask {
        Some(m) => Some(load_mask(m, &photo)?),
        None if pointing.is_some() => None,
        None => alpha_mask,
    };
    let target = match &args.material {
        Some(m) => Some(material_named(m)?),
        None => None,
    };
    let other = match &args.like {
        Some(p) => {
            let (img, alpha) = load_photo(p)?;
            let m = match &args.like_mask {
                Some(m) => Some(load_mask(m, &img)?),
                None => alpha,
            };
            Some((img, m))
        }
        None => None,
    };
    let nets = match &args.weights {
        Some(w) => Nets::load(w)?,
        None => Nets::builtin()?,
    }
    .with_mirror(!args.no_mirror);
    let renderer = Renderer::new(args.device)?;
    let known_normals = match &args.normals {
        Some(path) => Some(load_known_normals(path, &photo)?),
        None => None,
    };
    let known_light = |path: &Option<PathBuf>| -> Result<_, Failure> {
        let Some(path) = path else { return Ok(None) };
        let cfg = nets.config();
        let size = io::EnvSize::Size {
            height: cfg.env_height,
            width: cfg.env_width,
        };
        let loaded = io::load_env(path, Convention::Equirect)?;
        Ok(Some(io::resample::fit(loaded.env, size, path)?))
    };
    let known_env = known_light(&args.env)?;
    let like_env = known_light(&args.like_env)?;
    let steps = args
        .steps
        .unwrap_or_else(|| photo::default_steps(known_normals.is_some(), known_env.is_some()));
    let options = PhotoOptions {
        steps: if args.no_refine { 0 } else { steps },
        normal_steps: if args.no_refine { 0 } else { args.normal_steps },
        detail: args.detail,
        background_light: !args.no_background_light,
        normals: known_normals,
        env: known_env,
        ..PhotoOptions::default()
    };
    let load_s = t0.elapsed().as_secs_f64();
    let object = match &pointing {
        Some(p) => Object::Pointed(p),
        None => mask.as_deref().into(),
    };
    let d = photo::decompose(&renderer, &nets, &photo, object, &options, &mut |_| {})?;
    let t = Instant::now();
    let (material, like) = match (target, other) {
        (Some(m), _) => (m, None),
        (None, Some((img, m))) => {
            // what is known of the photo is not known of the other
            let like_options = PhotoOptions {
                normals: None,
                env: like_env,
                steps: match (args.no_refine, args.like_steps.or(args.steps)) {
                    (true, _) => 0,
                    (false, k) => {
                        k.unwrap_or_else(|| photo::default_steps(false, args.like_env.is_some()))
                    }
                },
                ..options.clone()
            };
            let o = photo::decompose(
                &renderer,
                &nets,
                &img,
                m.as_deref(),
                &like_options,
                &mut |_| {},
            )
            .map_err(|e| {
                Failure::from(matedit::Error::Invalid(format!(
                    "--like {}: {e}",
                    args.like
                        .as_ref()
                        .map_or(String::new(), |p| p.display().to_string())
                )))
            })?;
            (o.material.clone(), Some(o))
        }
        (None, None) => unreachable!("clap requires --material or --like"),
    };
    let like_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let edit = d.edit(&renderer, &photo, &material, None, Accuracy::Exact)?;
    let render_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let files = encode_outputs(&args.photo, kind, &photo, &edit, &d, &material)?;
    let mut stages = serde_json::Map::new();
    stages.insert("load".into(), json!(load_s));
    for (name, s) in &d.stages {
        stages.insert((*name).into(), json!(s));
    }
    if like.is_some() {
        stages.insert("like".into(), json!(like_s));
    }
    stages.insert("render".into(), json!(render_s));
    let report = json!({
        "photo": args.photo.display().to_string(),
        "size": [d.width, d.height],
        "pointing": pointing_json(pointing.as_ref()),
        "crop": {"x0": d.crop.x0, "y0": d.crop.y0, "size": d.crop.size},
        "object_pixels": d.mask.iter().filter(|&&m| m).count(),
        "material": material.name,
        "like": args.like.as_ref().map(|p| p.display().to_string()),
        "steps": d.losses.len(),
        "like_steps": like.as_ref().map(|o| o.losses.len()),
        "normal_steps": d.normal_losses.len().saturating_sub(1),
        "normal_loss_first": d.normal_losses.first(),
        "normal_loss_last": d.normal_losses.last(),
        "loss_first": d.losses.first(),
        "loss_last": d.losses.last(),
        "psnr_predicted_db": d.psnr_predicted,
        "psnr_refined_db": d.psnr_refined,
        "detail": d.detail,
        "light_level_from": d.light_factors.from.as_str(),
        "like_light_level_from": like.as_ref().map(|o| o.light_factors.from.as_str()),
        "light_factors": d.light_factors.gains,
        "seconds": stages,
    });
    io::create_dirs(&args.output)?;
    let mut staged = Vec::new();
    for (name, bytes) in &files {
        staged.push(io::write::stage(&args.output.join(name), bytes)?);
    }
    let mut report = report;
    report["seconds"]["write"] = json!(t.elapsed().as_secs_f64());
    report["seconds"]["total"] = json!(t0.elapsed().as_secs_f64());
    let mut text = serde_json::to_vec_pretty(&report).unwrap_or_default();
    text.push(b'\n');
    staged.push(io::write::stage(&args.output.join("report.json"), &text)?);
    for s in staged {
        s.commit()?;
    }
    let grey_card = |what: &str| {
        eprintln!(
            "matedit: edit: {what}: the background is black, so the photo is taken as exposed \
             for a grey card (exposed a stop brighter, the material would read twice as bright)"
        )
    };
    if d.light_factors.from == LevelFrom::GreyCard {
        grey_card(&args.photo.display().to_string());
    }
    if let (Some(o), Some(p)) = (&like, &args.like)
        && o.light_factors.from == LevelFrom::GreyCard
    {
        grey_card(&format!("--like {}", p.display()));
    }
    eprintln!(
        "matedit: edit: I' PSNR {:.2} dB predicted, {:.2} dB refined ({} steps); {:.2} s in all; wrote {}",
        d.psnr_predicted,
        d.psnr_refined,
        d.losses.len(),
        t0.elapsed().as_secs_f64(),
        args.output.display()
    );
    Ok(())
}

/// `--detail`: a number in [0, 1].
fn parse_detail(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        Ok(v) => Err(format!("{v} is outside [0, 1]")),
        Err(_) => Err(format!("'{s}' is not a number")),
    }
}

/// A photo, linear RGB, with a PNG's alpha as its mask (where it has one that is not
/// opaque everywhere).
pub(super) fn load_photo(path: &Path) -> Result<(Image, Option<Vec<bool>>), Failure> {
    let photo = io::load_image(path)?;
    let mask = match Format::of(path) {
        Some(Format::Png) => io::png_alpha_mask(path, &io::read_bytes(path)?)?,
        _ => None,
    };
    photo::check_photo(&photo)
        .map_err(|e| Failure::from(matedit::Error::file(path, e.to_string())))?;
    Ok((photo, mask))
}

fn load_mask(path: &Path, photo: &Image) -> Result<Vec<bool>, Failure> {
    let (w, h, m) = io::load_mask(path)?;
    if (w, h) != (photo.width, photo.height) {
        return Err(Failure::from(matedit::Error::file(
            path,
            format!(
                "mask is {w}x{h}, the photo {}x{}",
                photo.width, photo.height
            ),
        )));
    }
    photo::check_mask(&m, w, h)
        .map_err(|e| Failure::from(matedit::Error::file(path, e.to_string())))?;
    Ok(m)
}

/// `--normals`: a normal map of the photo's size.
fn load_known_normals(path: &Path, photo: &Image) -> Result<NormalMap, Failure> {
    let n = io::load_normals(path)?;
    if (n.width, n.height) != (photo.width, photo.height) {
        return Err(Failure::from(matedit::Error::file(
            path,
            format!(
                "normal map is {}x{}, the photo {}x{}",
                n.width, n.height, photo.width, photo.height
            ),
        )));
    }
    Ok(n)
}

/// A preset by name, or a material file.
fn material_named(name: &str) -> Result<Material, Failure> {
    if let Some(m) = matedit::presets::lookup(name) {
        return Ok(m);
    }
    let path = Path::new(name);
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        return Ok(io::load_material(path)?);
    }
    Err(Failure::from(matedit::Error::Invalid(format!(
        "--material {name}: not a preset (`matedit presets` lists them) nor a .json material file"
    ))))
}
