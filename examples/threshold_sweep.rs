//! Coverage and stereo consistency against the detection threshold (development aid).
use spslam::features::{AnmsMethod, ExtractorConfig, GrayImage, SuperPointExtractor};
use std::path::Path;
fn main() -> anyhow::Result<()> {
    let d = Path::new("../shared/data/kitti/sequences/06");
    let l = GrayImage::load(&d.join("image_0/000010.png"))?;
    let r = GrayImage::load(&d.join("image_1/000010.png"))?;
    for thr in [0.005f32, 0.002, 0.001] {
        for anms in [AnmsMethod::None, AnmsMethod::Kdtree, AnmsMethod::Ssc] {
            let mut ex = SuperPointExtractor::new(ExtractorConfig { threshold: thr, min_threshold: thr.min(0.00175), anms, ..Default::default() })?;
            let fl = ex.extract(l.view())?;
            let fr = ex.extract(r.view())?;
            let cols = 1226usize.div_ceil(32);
            let mut hit = vec![false; cols * 370usize.div_ceil(32)];
            for k in &fl.keypoints { hit[(k.y as usize / 32) * cols + k.x as usize / 32] = true; }
            let cov = hit.iter().filter(|&&h| h).count() as f64 / hit.len() as f64;
            // mutual NN
            let dim = fl.descriptor_len;
            let dist = |i: usize, j: usize| -> f32 { fl.descriptors[i*dim..(i+1)*dim].iter().zip(&fr.descriptors[j*dim..(j+1)*dim]).map(|(a,b)| (a-b)*(a-b)).sum() };
            let ab: Vec<usize> = (0..fl.len()).map(|i| (0..fr.len()).min_by(|&p,&q| dist(i,p).total_cmp(&dist(i,q))).unwrap()).collect();
            let ba: Vec<usize> = (0..fr.len()).map(|j| (0..fl.len()).min_by(|&p,&q| dist(p,j).total_cmp(&dist(q,j))).unwrap()).collect();
            let m: Vec<(usize,usize)> = ab.iter().enumerate().filter(|&(i,&j)| ba[j]==i).map(|(i,&j)|(i,j)).collect();
            let same = m.iter().filter(|&&(i,j)| (fl.keypoints[i].y - fr.keypoints[j].y).abs() <= 2.0).count();
            println!("thr {thr} {anms}: kps {} cov {:.1}% matches {} same-row {:.1}%", fl.len(), 100.0*cov, m.len(), 100.0*same as f64/m.len() as f64);
        }
    }
    Ok(())
}
