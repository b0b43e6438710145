"""Data that ships with the package or is fetched from package registries: the built-in parts
(:mod:`.parts`, with their part files under ``data/parts/``) and the real test data
(:mod:`.downloads`: Debian's CGAL meshes and PCL clouds, small_gicp's LiDAR pair).

``python -m scanalign.data fetch`` downloads and verifies the test data once.
"""
