//! `mocomp flowbench --out DIR PHOTO...`: the flow benchmark's pairs, made
//! from photographs under exactly known motion (see `synth::photo`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use crate::io::{flo, image, OutputFile};
use crate::raster::{array_to_plane, plane_to_array};
use crate::synth::photo::benchmark_pairs;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder to write into: one folder per pair (frame1.png, frame2.png,
    /// gt.flo, occ.png) and cases.csv.
    #[arg(long)]
    pub out: PathBuf,
    /// Source photographs (PNG, read as luma), at least 320 px wider and
    /// 200 px taller than the pairs so the camera stays inside them.
    #[arg(required = true)]
    pub photos: Vec<PathBuf>,
    /// Picture width of the pairs.
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    /// Picture height of the pairs.
    #[arg(long, default_value_t = 480)]
    pub height: usize,
}

pub fn run(args: &Args) -> Result<()> {
    if args.width < 16 || args.height < 16 || args.width > 4096 || args.height > 4096 {
        bail!("pair size {}x{} is outside 16..=4096", args.width, args.height);
    }
    let sources = args
        .photos
        .iter()
        .map(|p| {
            image::read_luma(p)
                .map(|pl| plane_to_array(&pl))
                .with_context(|| p.display().to_string())
        })
        .collect::<Result<Vec<_>>>()?;
    for (p, s) in args.photos.iter().zip(&sources) {
        if s.ncols() < args.width + 320 || s.nrows() < args.height + 200 {
            eprintln!(
                "note: {} is {}x{}, smaller than {}x{}: large motions will reach its edges",
                p.display(),
                s.ncols(),
                s.nrows(),
                args.width + 320,
                args.height + 200
            );
        }
    }
    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let mut csv = String::from("name,photo,width,height,mean_motion,max_motion,occluded_pct,valid_pct\n");
    let mut stdout = std::io::stdout().lock();
    for spec in benchmark_pairs(sources.len(), args.width, args.height) {
        let pair = spec.render(&sources);
        let dir = args.out.join(&spec.name);
        std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
        image::write_plane(&dir.join("frame1.png"), &array_to_plane(&pair.frame1)?)?;
        image::write_plane(&dir.join("frame2.png"), &array_to_plane(&pair.frame2)?)?;
        flo::write_flo(&dir.join("gt.flo"), &pair.flow)?;
        let occ = pair.occluded.mapv(|o| if o { 255.0 } else { 0.0 });
        image::write_plane(&dir.join("occ.png"), &array_to_plane(&occ)?)?;
        let n = (args.width * args.height) as f64;
        let occluded = pair.occluded.iter().filter(|&&o| o).count() as f64;
        csv += &format!(
            "{},{},{},{},{:.2},{:.2},{:.2},{:.2}\n",
            spec.name,
            args.photos[spec.background].display(),
            args.width,
            args.height,
            pair.flow.mean_magnitude(),
            pair.flow.max_magnitude(),
            100.0 * occluded / n,
            100.0 * pair.flow.valid_count() as f64 / n
        );
        writeln!(
            stdout,
            "{}: mean motion {:.1} px, max {:.1} px, {:.1} % occluded",
            spec.name,
            pair.flow.mean_magnitude(),
            pair.flow.max_magnitude(),
            100.0 * occluded / n
        )?;
    }
    let path = args.out.join("cases.csv");
    let mut file = OutputFile::create(&path).with_context(|| path.display().to_string())?;
    file.write_all(csv.as_bytes())?;
    file.commit()?;
    Ok(())
}
