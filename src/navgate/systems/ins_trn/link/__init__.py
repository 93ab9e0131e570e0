"""Seed 000's PS <-> Pi link: the frame format between the Zynq's ARM and the TRN service
(docs/seed000-link.md when written). Imports nothing of seed 000."""
