from setuptools import find_packages, setup
from catkin_pkg.python_setup import generate_distutils_setup

# every subpackage of patrolling_sim (its layers), so that an install space holds them all
setup(**generate_distutils_setup(packages=find_packages("src"), package_dir={"": "src"}))
