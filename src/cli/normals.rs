//! `matedit normals`: a normal map (and a mask) from a mesh file or a procedural shape.

use std::path::PathBuf;

use matedit::io::{self, Format};
use matedit::shapes::{self, Rotation, Shape, View};
use matedit::{Camera, Error};

use super::shared::{Failure, parse_fov, runtime};

/// Shown after the options by `matedit help normals`.
pub const EXAMPLES: &str = "\
Examples:
  matedit normals --mesh bunny.obj -o bunny.png --mask bunny_mask.png
  matedit normals --shape blobby --seed 7 -o blob.exr --size 512
  matedit normals --shape torus:seed=3 -o torus.npy --size 240x320 --fov 40 --rotate 30,-20,0
  matedit normals --shape box --flat -o box.png
  matedit render --normals blob.exr -o blob_render.png

Meshes: .obj, .ply, .stl, .off (.gltf, .glb with --features gltf). Shapes: sphere, blobby, superquadric, torus,
capsule, box, cylinder, plate, limb, extrusion, union, random, vessel; KIND:seed=N fixes a shape's
own seed. Outputs: .exr or .npy (float32 n.x, n.y, n.z; background 0), .png (8-bit RGBA,
v = (n + 1) / 2 * 255, alpha = the mask). See docs/shapes.md.";

/// The options of `matedit normals`.
#[derive(clap::Args)]
pub struct Args {
    /// A triangle mesh: .obj, .ply, .stl, .off (.gltf or .glb when built with --features gltf).
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "shape",
        conflicts_with = "shape"
    )]
    mesh: Option<PathBuf>,
    /// A procedural shape: KIND or KIND:seed=N (see below).
    #[arg(long, value_name = "SPEC", value_parser = clap::value_parser!(Shape))]
    shape: Option<Shape>,
    /// Output normal map (.exr, .npy or .png).
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// Image size: N (square) or HxW [default: 256].
    #[arg(long, value_name = "N|HxW", value_parser = parse_size)]
    size: Option<(usize, usize)>,
    /// Perspective camera with this vertical field of view in degrees [default: orthographic].
    #[arg(long, value_name = "DEG", value_parser = parse_fov)]
    fov: Option<f64>,
    /// The object's rotation in degrees: yaw about +y, then pitch about +x, then roll about +z [default: none, or drawn from --seed].
    #[arg(long, value_name = "YAW,PITCH,ROLL", allow_hyphen_values = true, value_parser = clap::value_parser!(Rotation))]
    rotate: Option<Rotation>,
    /// Seed of the shape's random parameters (unless its spec has one) and, without --rotate, of a uniformly random rotation.
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Face normals (flat shading) instead of interpolated vertex normals.
    #[arg(long, conflicts_with = "crease")]
    flat: bool,
    /// A mesh file without normals of its own gets its vertex normals smoothed only across
    /// edges whose faces meet within DEG degrees: sharper edges stay sharp (docs/shapes.md).
    #[arg(long, value_name = "DEG", value_parser = parse_crease)]
    crease: Option<f64>,
    /// Fraction of the frame's half-size left empty on each side of the object.
    #[arg(long, value_name = "FRAC", default_value_t = shapes::DEFAULT_MARGIN, value_parser = parse_margin)]
    margin: f64,
    /// Also write the mask (.png: 8-bit, 255 on the object; .npy or .exr: 1 on the object).
    #[arg(long, value_name = "FILE")]
    mask: Option<PathBuf>,
}

const SIDE_MAX: usize = 8192;

/// `--size`: N or HxW, each side in 1..=8192.
fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("size '{s}' is not N or HEIGHTxWIDTH (e.g. 256 or 240x320)");
    let side = |v: &str| v.trim().parse::<usize>().map_err(|_| bad());
    let (h, w) = match s.split_once(['x', 'X']) {
        Some((h, w)) => (side(h)?, side(w)?),
        None => (side(s)?, side(s)?),
    };
    if h == 0 || w == 0 || h > SIDE_MAX || w > SIDE_MAX {
        return Err(format!(
            "size '{s}': each side must be between 1 and {SIDE_MAX}"
        ));
    }
    Ok((h, w))
}

/// `--margin`: a number in [0, 1).
fn parse_margin(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.0..1.0).contains(&v) => Ok(v),
        _ => Err(format!("margin '{s}' is not a number in [0, 1)")),
    }
}

/// Runs `matedit normals`.
pub fn run(args: &Args) -> Result<(), Failure> {
    const OUTPUTS: [Format; 3] = [Format::Exr, Format::Npy, Format::Png];
    io::check_output(&args.output, &OUTPUTS)?;
    if let Some(mask) = &args.mask {
        io::write::check_output(mask, &OUTPUTS)?;
        if *mask == args.output {
            return Err(
                Error::file(mask, "is also the normal map's output; give another file").into(),
            );
        }
    }
    let seed = args.seed.unwrap_or(0);
    let (mesh, source) = match (&args.mesh, &args.shape) {
        (Some(path), _) => {
            let mesh = shapes::load_mesh(path)?;
            let mesh = match args.crease {
                Some(degrees) => mesh.creased(degrees),
                None => mesh,
            };
            (mesh, path.display().to_string())
        }
        (None, Some(shape)) => (
            shape.mesh(seed),
            format!("{shape} (seed {})", shape.seed.unwrap_or(seed)),
        ),
        (None, None) => {
            return Err(Error::Invalid("give --mesh FILE or --shape SPEC".into()).into());
        }
    };
    let rotation = match (args.rotate, args.seed) {
        (Some(r), _) => r,
        (None, Some(s)) => Rotation::random(s),
        (None, None) => Rotation::default(),
    };
    let (height, width) = args.size.unwrap_or((256, 256));
    let view = View {
        width,
        height,
        camera: args
            .fov
            .map_or(Camera::Orthographic, |fov_y_deg| Camera::Perspective {
                fov_y_deg,
            }),
        rotation,
        flat: args.flat,
        margin: args.margin,
    };
    let (map, mask) = shapes::render_normals(&mesh, &view)?;
    let mut staged = vec![
        io::stage(
            &args.output,
            &io::encode_normals(&args.output, &map, &mask)?,
        )
        .map_err(runtime)?,
    ];
    if let Some(path) = &args.mask {
        let bytes = io::encode_mask(path, width, height, &mask)?;
        staged.push(io::stage(path, &bytes).map_err(runtime)?);
    }
    let written = io::commit_all(staged).map_err(runtime)?;
    let covered = mask.iter().filter(|&&m| m).count();
    eprintln!(
        "matedit: {source}: {} triangles, rotation {:.1},{:.1},{:.1}; {covered} of {} pixels on the object",
        mesh.triangles.len(),
        rotation.yaw,
        rotation.pitch,
        rotation.roll,
        width * height
    );
    for p in written {
        eprintln!("matedit: wrote {} ({width}x{height})", p.display());
    }
    Ok(())
}

/// `--crease`: an angle in (0, 180] degrees.
fn parse_crease(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    shapes::check_crease(v)
}
