//! The [`Master`] methods for tools: any ESC register of a slave, its SII image and words,
//! and its station alias.

use std::sync::Arc;

use crate::master::{Master, MasterError, SlaveAddress};

use super::tools;

impl Master {
    /// The SII image of the slave at `address` as the scan (or the watch) read it; see
    /// [`Master::read_sii`] for a fresh read.
    pub fn sii_image(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        self.ctx.resolve_with(address, |r| r.sii.clone())
    }

    /// Reads `len` bytes at register `ado` of the slave at `address`.
    pub async fn read_register(
        &self,
        address: SlaveAddress,
        ado: u16,
        len: usize,
    ) -> Result<Vec<u8>, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { tools::read_register(&ctx, address, ado, len).await })
            .await
    }

    /// Writes `data` at register `ado` of the slave at `address`.
    pub async fn write_register(
        &self,
        address: SlaveAddress,
        ado: u16,
        data: &[u8],
    ) -> Result<(), MasterError> {
        let ctx = Arc::clone(&self.ctx);
        let data = data.to_vec();
        self.run(async move { tools::write_register(&ctx, address, ado, data).await })
            .await
    }

    /// Writes `data` at register `ado` of the slave at `address` and returns the contents
    /// from before the write, in one FPRW datagram.
    pub async fn read_write_register(
        &self,
        address: SlaveAddress,
        ado: u16,
        data: &[u8],
    ) -> Result<Vec<u8>, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        let data = data.to_vec();
        self.run(async move { tools::read_write_register(&ctx, address, ado, data).await })
            .await
    }

    /// Reads the whole SII image of the slave at `address` (from the slave, not a cache).
    pub async fn read_sii(&self, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { tools::read_sii(&ctx, address).await })
            .await
    }

    /// Writes SII words from word `start` on. The checksum (word 7) is not touched; use
    /// [`Master::set_alias`] for the alias.
    pub async fn write_sii(
        &self,
        address: SlaveAddress,
        start: u16,
        words: &[u16],
    ) -> Result<(), MasterError> {
        let ctx = Arc::clone(&self.ctx);
        let words = words.to_vec();
        self.run(async move { tools::write_sii(&ctx, address, start, &words).await })
            .await
    }

    /// Sets the station alias of the slave at `address` in its SII (word 4, checksum in
    /// word 7 kept valid) and in its alias register (EEPROM reload), so that it is
    /// reachable as [`SlaveAddress::Alias`] at once and after a power cycle. Returns the
    /// alias register read back.
    pub async fn set_alias(&self, address: SlaveAddress, alias: u16) -> Result<u16, MasterError> {
        let ctx = Arc::clone(&self.ctx);
        self.run(async move { tools::set_alias(&ctx, address, alias).await })
            .await
    }
}
