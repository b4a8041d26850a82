"""Split files: their schemas, versions, writer and reader, and the loaders (public name:
:mod:`simlidar.data`)."""
