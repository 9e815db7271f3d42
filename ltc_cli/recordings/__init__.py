"""Recordings: opening them with a reader, images, masks (RLE) and ground truth."""
