"""simlidar: synthetic LiDAR temporal-pulse datasets and benchmarks.

Rebuilds the "Sim LiDAR" dataset of Wang et al., "Temporal Pulses Driven Spiking Neural Network
for Fast Object Recognition in Autonomous Driving" (IJCAI 2020) by ray casting a simulated
Velodyne VLP-16 into procedurally built road scenes.
"""

__version__ = "0.1.0"
