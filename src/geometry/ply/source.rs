//! The PLY file, read through one buffer that the payload is decoded from in place
//! (the file is never held whole: a 20M-triangle mesh is 380 MB of it).

use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::Parse;

/// The file, read through one buffer: the payload is decoded from it in place.
pub(super) struct Source {
    file: File,
    buf: Vec<u8>,
    pos: usize,
    end: usize,
    /// Bytes of the file not yet read into `buf`.
    left: u64,
}

const CHUNK: usize = 1 << 20;

impl Source {
    pub(super) fn open(path: &Path) -> std::io::Result<Source> {
        let file = File::open(path)?;
        let left = file.metadata()?.len();
        Ok(Source {
            file,
            buf: vec![0; CHUNK],
            pos: 0,
            end: 0,
            left,
        })
    }

    /// Bytes not yet consumed.
    pub(super) fn remaining(&self) -> u64 {
        (self.end - self.pos) as u64 + self.left
    }

    /// Reads more of the file into the buffer, keeping the unconsumed bytes (growing
    /// the buffer when they fill it); false at the end of the file.
    fn refill(&mut self) -> Parse<bool> {
        if self.left == 0 {
            return Ok(false);
        }
        self.buf.copy_within(self.pos..self.end, 0);
        self.end -= self.pos;
        self.pos = 0;
        if self.end == self.buf.len() {
            self.buf.resize(2 * self.buf.len(), 0);
        }
        let k = self
            .file
            .read(&mut self.buf[self.end..])
            .map_err(|e| format!("cannot read the file: {e}"))?;
        if k == 0 {
            // The file shrank since it was opened.
            self.left = 0;
            return Ok(false);
        }
        self.end += k;
        self.left = self.left.saturating_sub(k as u64);
        Ok(true)
    }

    /// The next `n` bytes.
    #[inline]
    pub(super) fn take(&mut self, n: usize) -> Parse<&[u8]> {
        while self.end - self.pos < n {
            if n as u64 > self.remaining() || !self.refill()? {
                return Err("the file ends".into());
            }
        }
        let b = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(b)
    }

    /// The next line, without its `\n` (empty at the end of the file).
    pub(super) fn line(&mut self) -> Parse<&[u8]> {
        let mut scanned = 0;
        loop {
            if let Some(j) = self.buf[self.pos + scanned..self.end]
                .iter()
                .position(|&b| b == b'\n')
            {
                let start = self.pos;
                self.pos += scanned + j + 1;
                return Ok(&self.buf[start..start + scanned + j]);
            }
            scanned = self.end - self.pos;
            if !self.refill()? {
                let start = self.pos;
                self.pos = self.end;
                return Ok(&self.buf[start..self.end]);
            }
        }
    }

    /// Whether anything but whitespace follows.
    pub(super) fn any_non_whitespace(&mut self) -> Parse<bool> {
        loop {
            if self.buf[self.pos..self.end]
                .iter()
                .any(|b| !b.is_ascii_whitespace())
            {
                return Ok(true);
            }
            self.pos = self.end;
            if !self.refill()? {
                return Ok(false);
            }
        }
    }
}
