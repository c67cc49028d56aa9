//! The mailbox engine: one owner per slave mailbox, and the CoE, SoE, FoE, VoE and EoE clients.
