//! The training images: every PNG and JPEG of each folder, in name order,
//! optionally thinned to an evenly spaced subset.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// Extensions read as images (compared without case).
const IMAGE_EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

/// Every image file directly in each of `dirs`, in name order per folder,
/// the folders in the order given. A folder without images is an error.
pub fn list_images(dirs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut all = Vec::new();
    for dir in dirs {
        let mut found = images_in(dir)?;
        if found.is_empty() {
            bail!(
                "{} holds no PNG or JPEG images (folders are not searched recursively)",
                dir.display()
            );
        }
        found.sort();
        all.extend(found);
    }
    Ok(all)
}

fn images_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir)
        .with_context(|| format!("cannot list the image folder {}", dir.display()))?;
    let mut found = Vec::new();
    for entry in entries {
        let path = entry
            .with_context(|| format!("cannot list the image folder {}", dir.display()))?
            .path();
        let is_image = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        if is_image && path.is_file() {
            found.push(path);
        }
    }
    Ok(found)
}

/// At most `max` of `paths`, evenly spaced (the first always kept):
/// index `i · n / max` for `i` in `0..max`.
pub fn subsample(paths: Vec<PathBuf>, max: Option<usize>) -> Result<Vec<PathBuf>> {
    let n = paths.len();
    match max {
        Some(0) => bail!("--max-images must be at least 1"),
        Some(max) if max < n => Ok((0..max).map(|i| paths[i * n / max].clone()).collect()),
        _ => Ok(paths),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subsampling_is_even_and_keeps_the_first() {
        let paths: Vec<PathBuf> = (0..51)
            .map(|i| PathBuf::from(format!("{i:06}.png")))
            .collect();
        let picked = subsample(paths.clone(), Some(6)).unwrap();
        let names: Vec<String> = picked.iter().map(|p| p.display().to_string()).collect();
        assert_eq!(
            names,
            [
                "000000.png",
                "000008.png",
                "000017.png",
                "000025.png",
                "000034.png",
                "000042.png"
            ]
        );
        assert_eq!(subsample(paths.clone(), Some(100)).unwrap(), paths);
        assert_eq!(subsample(paths.clone(), None).unwrap(), paths);
        assert!(subsample(paths, Some(0)).is_err());
    }

    #[test]
    fn only_images_directly_in_the_folder_in_name_order() {
        let dir = std::env::temp_dir().join(format!("spslam-vocab-list-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub.png")).unwrap();
        for name in ["b.PNG", "a.jpg", "c.jpeg", "notes.txt"] {
            std::fs::write(dir.join(name), b"x").unwrap();
        }
        let found = list_images(std::slice::from_ref(&dir)).unwrap();
        let names: Vec<_> = found
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["a.jpg", "b.PNG", "c.jpeg"]);
        std::fs::remove_dir_all(&dir).unwrap();
        let err = list_images(std::slice::from_ref(&dir)).unwrap_err();
        assert!(format!("{err:#}").contains(&dir.display().to_string()));
    }
}
