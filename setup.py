# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""ament_python setup for wheel_force_estimator."""
from glob import glob

from setuptools import find_packages
from setuptools import setup

package_name = 'wheel_force_estimator'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/vehicles', glob('config/vehicles/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    package_data={package_name: ['py.typed']},
    install_requires=[
        'setuptools',
        'numpy>=1.24',
        'scipy>=1.10',
        'matplotlib>=3.6',
        'pyyaml>=6',
        'tqdm>=4.60',
        'numba>=0.58',
        'rosbags>=0.11',
        # MATLAB v7.3 (HDF5) generic recordings
        'h5py>=3.0',
        # wheel-force fleet: one task per bag on a Dask cluster (local or remote)
        'dask>=2024.1',
        'distributed>=2024.1',
    ],
    extras_require={
        # faster mcap chunk CRCs (bagio/checksum.py; the stdlib zlib fallback gives equal values)
        # and zstd chunks (bagio/compression.py; backports.zstd from rosbags gives equal bytes)
        'fast': ['isal>=1.0', 'zstandard>=0.21'],
        # what `colcon test` (python -m pytest on test/) needs besides the ament linters
        'test': ['pytest', 'pytest-timeout', 'lxml', 'catkin_pkg', 'mcap'],
    },
    zip_safe=True,
    maintainer='wheel_force_estimator maintainers',
    maintainer_email='wheel-force@example.com',
    description='Virtual wheel force transducer (MIMO FRF) for ROS 2 with durability metrics.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'wheel-force = wheel_force_estimator.cli.main:main',
            'wheel_force_node = wheel_force_estimator.ros.run:main',
        ],
    },
)
