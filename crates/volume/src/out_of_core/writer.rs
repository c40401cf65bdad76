//! [`CacheWriter`]: builds a brick cache file from 8³ blocks streamed in any order, grid
//! by grid and leaf by leaf, holding only the brick table and records in memory (about
//! 4 bytes per table cell and 48 per brick; the values go straight to disk).
//!
//! Dense blocks are appended to the VALUES section as they arrive (in the input's own
//! order: OpenVDB's tree order, or z-slabs of the generator, both of which keep
//! neighbouring bricks close). [`CacheWriter::finish`] maps what was written, builds the
//! pyramid from per-brick bounds and the FNEE proxy power from the mapped volume with the
//! same code as an in-core render, then writes the remaining sections and the header, and
//! renames the temporary file into place: a cache file is complete or absent.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DAffine3, IVec3};
use xxhash_rust::xxh3::Xxh3;

use super::format::{
    Header, Meta, ProxyMeta, SectionEntry, SectionKind, BYTE_ORDER, CHUNK, MAGIC, MAX_SECTIONS,
    PAGE, VERSION,
};
use crate::brick::{BlockSink, BrickTableBuilder, Channel};
use crate::grid::LEAF_VOXELS;
use crate::out_of_core::mapfault::Mapping;
use crate::out_of_core::storage::Buffer;
use crate::proxy::CellPower;
use crate::Volume;
use plume_core::error::{Error, Result};

/// What a fault in the temporary file's mapping calls it (`mapfault`).
const WRITING: &str = "brick cache being written";

/// Hashes a byte stream in [`CHUNK`]-sized chunks.
#[derive(Default)]
struct ChunkHasher {
    hasher: Xxh3,
    fill: u64,
    sums: Vec<u64>,
}

impl ChunkHasher {
    fn update(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let take = ((CHUNK - self.fill) as usize).min(bytes.len());
            self.hasher.update(&bytes[..take]);
            self.fill += take as u64;
            bytes = &bytes[take..];
            if self.fill == CHUNK {
                self.sums.push(self.hasher.digest());
                self.hasher.reset();
                self.fill = 0;
            }
        }
    }

    /// Close the section: the last partial chunk gets its sum.
    fn finish_section(&mut self) {
        if self.fill > 0 {
            self.sums.push(self.hasher.digest());
            self.hasher.reset();
            self.fill = 0;
        }
    }
}

/// The output file and its position, section bookkeeping and chunk sums.
struct Out {
    path: PathBuf,
    /// The cache file being made: what write errors name.
    target: PathBuf,
    /// Removes the temporary file `path` unless it was renamed into place.
    temporary: plume_core::fs::TemporaryFile,
    file: BufWriter<File>,
    pos: u64,
    chunks: ChunkHasher,
    sections: Vec<SectionEntry>,
    open: Option<SectionEntry>,
    /// Dense blocks appended to VALUES.
    blocks: u64,
    readback: Option<Arc<Mapping>>,
}

impl Out {
    fn io(&self, e: std::io::Error) -> Error {
        Error::Write { path: self.target.clone(), source: e }
    }

    fn write(&mut self, bytes: &[u8]) -> Result<()> {
        self.file.write_all(bytes).map_err(|e| self.io(e))?;
        self.chunks.update(bytes);
        self.pos += bytes.len() as u64;
        Ok(())
    }

    fn begin(&mut self, kind: SectionKind) -> Result<()> {
        let pad = self.pos.next_multiple_of(PAGE) - self.pos;
        self.file.write_all(&vec![0u8; pad as usize]).map_err(|e| self.io(e))?;
        self.pos += pad;
        self.open = Some(SectionEntry {
            kind: kind as u32,
            first_chunk: self.chunks.sums.len() as u32,
            offset: self.pos,
            len: 0,
            checksum: 0,
        });
        Ok(())
    }

    fn end(&mut self) {
        let mut s = self.open.take().expect("invariant: a section is open");
        s.len = self.pos - s.offset;
        self.chunks.finish_section();
        self.sections.push(s);
    }

    fn section(&mut self, kind: SectionKind, bytes: &[u8]) -> Result<()> {
        self.begin(kind)?;
        self.write(bytes)?;
        self.end();
        Ok(())
    }
}

impl BlockSink for Out {
    fn append(&mut self, block: &[f32; LEAF_VOXELS]) -> Result<u32> {
        let index = u32::try_from(self.blocks)
            .map_err(|_| Error::Scene("the volume has more than 2³² dense bricks".into()))?;
        self.write(bytemuck::cast_slice(block))?;
        self.blocks += 1;
        Ok(index)
    }

    fn appended(&mut self) -> Result<&[f32]> {
        self.file.flush().map_err(|e| self.io(e))?;
        // The temporary file is ours alone until it is renamed, and not written while this
        // mapping is in use (`finish` drops it before writing on)
        let map = Mapping::map(self.file.get_ref(), &self.path, WRITING).map_err(|e| self.io(e))?;
        let map = self.readback.insert(Arc::new(map));
        let start = PAGE as usize;
        let bytes = &map[start..start + self.blocks as usize * LEAF_VOXELS * 4];
        Ok(bytemuck::cast_slice(bytes))
    }
}

/// What the cache records besides the bricks (see [`Meta`]).
#[derive(Clone, Debug)]
pub struct CacheInfo {
    /// Density grid name.
    pub density_grid: String,
    /// Source grid name, if any.
    pub source_grid: Option<String>,
    /// Albedo grid name, if any.
    pub albedo_grid: Option<String>,
    /// `Emission::source_key` the sources were mapped with.
    pub source_key: String,
    /// Emission kind name.
    pub emission_kind: String,
    /// The input converted, `None` for generated data.
    pub input: Option<super::format::InputFingerprint>,
    /// Grid backgrounds (raw, before mapping for the source): density, source, albedo.
    pub backgrounds: [Option<f32>; 3],
}

/// FNEE proxy power to store: resolution, key and the power function.
pub struct ProxySpec<'a> {
    /// Cells along the longest axis (`None`: the default for the volume's size).
    pub resolution: Option<u32>,
    /// `Emission::light_key`.
    pub power_key: String,
    /// `integrator::light_power`.
    pub power: &'a (dyn Fn(f32, f32) -> f64 + Sync),
}

/// Streams bricks into a new cache file. See the module docs.
pub struct CacheWriter {
    final_path: PathBuf,
    out: Out,
    builder: BrickTableBuilder,
    world_from_index: DAffine3,
    /// Clean-up counts of an earlier build, added to this one's (for [`write_volume`]).
    report_base: crate::brick::BuildReport,
}

impl CacheWriter {
    /// Start writing `path` (through a temporary file beside it) for a volume whose bricks
    /// lie in `brick_lo .. brick_lo + dims`.
    ///
    /// # Errors
    /// A table too large, or the file cannot be created.
    pub fn create(
        path: &Path,
        world_from_index: DAffine3,
        brick_lo: IVec3,
        dims: IVec3,
        what: &str,
    ) -> Result<CacheWriter> {
        let builder = BrickTableBuilder::new(brick_lo, dims, what)?;
        // A killed conversion leaves its temporary (tens of GB at scale): remove those of
        // dead processes, as renders do for their outputs
        plume_core::fs::remove_stale_temporaries(path);
        let tmp = plume_core::fs::temporary_path(path);
        // Read access too: `finish` maps the values written so far
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)
            .map_err(|e| Error::Write { path: path.into(), source: e })?;
        let mut out = Out {
            temporary: plume_core::fs::TemporaryFile::new(tmp.clone()),
            path: tmp,
            target: path.to_path_buf(),
            file: BufWriter::with_capacity(8 << 20, file),
            pos: 0,
            chunks: ChunkHasher::default(),
            sections: Vec::new(),
            open: None,
            blocks: 0,
            readback: None,
        };
        // Header page, rewritten at the end
        out.file.write_all(&[0u8; PAGE as usize]).map_err(|e| out.io(e))?;
        out.pos = PAGE;
        out.begin(SectionKind::Values)?;
        Ok(CacheWriter {
            final_path: path.to_path_buf(),
            out,
            builder,
            world_from_index,
            report_base: Default::default(),
        })
    }

    /// Store channel `channel` of brick `b` from 512 values in OpenVDB leaf order, each
    /// passed through `map` (the source mapping; identity otherwise) and cleaned exactly
    /// as an in-core build cleans them.
    ///
    /// # Errors
    /// `b` outside the announced box, or a write error.
    pub fn put(
        &mut self,
        b: IVec3,
        channel: Channel,
        leaf_values: &[f32],
        map: impl Fn(f32) -> f32,
    ) -> Result<()> {
        self.builder.put(&mut self.out, b, channel, leaf_values, map)
    }

    /// Store channel `channel` of brick `b` as a constant (a voxelized tile).
    ///
    /// # Errors
    /// `b` outside the announced box.
    pub fn put_constant(&mut self, b: IVec3, channel: Channel, value: f32) -> Result<()> {
        self.builder.put_constant(b, channel, value)
    }

    /// Bytes of values written so far.
    #[must_use]
    pub fn bytes_written(&self) -> u64 {
        self.out.pos
    }

    /// Finish the file: table, bricks, pyramid, proxy power, metadata, checksums, header;
    /// then rename it into place.
    ///
    /// # Errors
    /// Write errors (the temporary file is removed), or invalid proxy settings.
    pub fn finish(self, info: &CacheInfo, proxy: Option<ProxySpec<'_>>) -> Result<PathBuf> {
        let tmp = self.out.path.clone();
        let result = self.finish_inner(info, proxy);
        if result.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        result
    }

    fn finish_inner(self, info: &CacheInfo, proxy: Option<ProxySpec<'_>>) -> Result<PathBuf> {
        let CacheWriter { final_path, mut out, builder, world_from_index, report_base } = self;
        let mut built = builder.finish(&mut out, info.backgrounds)?;
        built.report.density_clamped += report_base.density_clamped;
        built.report.source_invalid += report_base.source_invalid;
        built.report.albedo_clamped += report_base.albedo_clamped;
        out.end(); // VALUES
        out.file.flush().map_err(|e| out.io(e))?;
        // The volume over the values as written, to compute what an in-core render would
        let values_entry = out.sections[0];
        // As in `appended`; the values are complete and no longer written
        let map =
            Arc::new(Mapping::map(out.file.get_ref(), &out.path, WRITING).map_err(|e| out.io(e))?);
        let values =
            Buffer::<f32>::mapped(&map, values_entry.offset as usize, values_entry.len as usize)
                .expect("invariant: the values section is page-aligned and whole blocks");
        let report = built.report;
        let brick_count = built.bricks.len() as u64;
        let volume = Volume::from_table(world_from_index, built, values);
        let proxy_power = match &proxy {
            Some(spec) => {
                let resolution = crate::proxy::ProxyGrid::resolution_for(&volume, spec.resolution);
                CellPower::sum(&volume, resolution, spec.power)?
            }
            None => None,
        };
        out.section(SectionKind::Table, bytemuck::cast_slice(&volume.table))?;
        out.section(SectionKind::Bricks, bytemuck::cast_slice(&volume.bricks))?;
        out.begin(SectionKind::Pyramid)?;
        for level in &volume.pyramid.levels {
            out.write(bytemuck::cast_slice(&level.nodes))?;
        }
        out.end();
        out.section(
            SectionKind::Proxy,
            proxy_power.as_ref().map_or(&[][..], |p| bytemuck::cast_slice(&p.sums)),
        )?;
        let m = world_from_index.matrix3.to_cols_array();
        let t = world_from_index.translation;
        let meta = Meta {
            format: "plume brick cache".into(),
            writer: format!("plume {}", env!("CARGO_PKG_VERSION")),
            world_from_index: [m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], t.x, t.y, t.z],
            brick_lo: volume.brick_lo.to_array(),
            dims: volume.dims.to_array(),
            brick_count,
            value_blocks: out.blocks,
            density_grid: info.density_grid.clone(),
            source_grid: info.source_grid.clone(),
            albedo_grid: info.albedo_grid.clone(),
            source_key: info.source_key.clone(),
            emission_kind: info.emission_kind.clone(),
            input: info.input.clone(),
            proxy: proxy_power.as_ref().zip(proxy.as_ref()).map(|(p, spec)| ProxyMeta {
                resolution: p.resolution,
                power_key: spec.power_key.clone(),
            }),
            report,
        };
        drop(volume);
        drop(map);
        out.readback = None;
        let json = serde_json::to_vec(&meta).expect("invariant: metadata serializes");
        out.section(SectionKind::Meta, &json)?;
        // CHUNKS: not chunk-hashed itself; its whole hash goes in the header
        let sums = std::mem::take(&mut out.chunks.sums);
        let sum_bytes: &[u8] = bytemuck::cast_slice(&sums);
        out.begin(SectionKind::Chunks)?;
        out.file.write_all(sum_bytes).map_err(|e| out.io(e))?;
        out.pos += sum_bytes.len() as u64;
        let mut chunks_entry = out.open.take().expect("invariant: open");
        chunks_entry.len = sum_bytes.len() as u64;
        chunks_entry.checksum = xxhash_rust::xxh3::xxh3_64(sum_bytes);
        out.sections.push(chunks_entry);

        let mut header = Header {
            magic: MAGIC,
            version: VERSION,
            byte_order: BYTE_ORDER,
            section_count: out.sections.len() as u32,
            reserved: 0,
            sections: [SectionEntry::default(); MAX_SECTIONS],
            checksum: 0,
        };
        header.sections[..out.sections.len()].copy_from_slice(&out.sections);
        header.checksum = header.compute_checksum();
        let tmp = out.path.clone();
        let mut file = out
            .file
            .into_inner()
            .map_err(|e| Error::Write { path: final_path.clone(), source: e.into_error() })?;
        let io = |e| Error::Write { path: final_path.clone(), source: e };
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        file.write_all(bytemuck::bytes_of(&header)).map_err(io)?;
        // No fsync: the kernel writes the pages back in its own time. A cache torn by a
        // crash before that fails its checksums when opened and is rebuilt or refused,
        // never trusted, so waiting here for gigabytes to reach the disk buys nothing.
        drop(file);
        std::fs::rename(&tmp, &final_path)
            .map_err(|e| Error::Write { path: final_path.clone(), source: e })?;
        out.temporary.keep();
        Ok(final_path)
    }
}

/// Write `volume` (built in memory) as a cache file: every brick in table order, so the
/// cache renders bit-identically to `volume`.
///
/// # Errors
/// As [`CacheWriter::finish`].
pub fn write_volume(
    path: &Path,
    volume: &Volume,
    info: &CacheInfo,
    proxy: Option<ProxySpec<'_>>,
) -> Result<PathBuf> {
    use crate::brick::Slot;
    use crate::builder::{slot_at, LEAF_TO_BRICK};
    let mut w = CacheWriter::create(
        path,
        volume.world_from_index(),
        volume.brick_lo,
        volume.dims,
        &info.density_grid,
    )?;
    let mut leaf = [0.0f32; LEAF_VOXELS];
    let (lo, dims) = (volume.brick_lo, volume.dims);
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let b = lo + IVec3::new(x, y, z);
                let Some(brick) = volume.brick(b) else { continue };
                for (channel, slot) in [
                    (Channel::Density, brick.density),
                    (Channel::Source, brick.source),
                    (Channel::Albedo, brick.albedo),
                ] {
                    match slot.get() {
                        Slot::Constant(v) => w.put_constant(b, channel, v)?,
                        Slot::Dense(_) => {
                            for (v, &at) in leaf.iter_mut().zip(LEAF_TO_BRICK.iter()) {
                                *v = slot_at(&volume.values, slot, usize::from(at));
                            }
                            w.put(b, channel, &leaf, |v| v)?;
                        }
                    }
                }
            }
        }
    }
    w.report_base = volume.report;
    w.finish(info, proxy)
}
