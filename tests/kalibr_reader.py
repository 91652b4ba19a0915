"""Kalibr's IMU config reader, mirrored key by key and check by check (it is ROS-bound).

Source: ethz-asl/kalibr, ``aslam_offline_calibration/kalibr/python/kalibr_common/
ConfigReader.py`` (commits 0b8b9e8 and ea2791f read alike here), classes
``ParametersBase`` and ``ImuParameters``.  What it does, quoted::

    def readYaml(self):
        ...
                data = yaml.safe_load(f)
    ...
    def catch_keyerror(f):
        ...
            except KeyError as e:
                args[0].raiseError("Field {0} missing in file: {1}".format(e, args[0].yamlFile))
    ...
    def raiseError(self, message):
        header = "[{0} Reader]: ".format(self.name)
        raise RuntimeError( "{0}{1}".format(header, message) )

    class ImuParameters(ParametersBase):
        def __init__(self, yamlFile, createYaml=False):
            ParametersBase.__init__(self, yamlFile, "ImuConfig", createYaml)
        def checkRosTopic(self, topic):
            if not isinstance(topic, str):
                self.raiseError("rostopic has to be a string")
        @catch_keyerror
        def getRosTopic(self):
            self.checkRosTopic(self.data["rostopic"])
            return self.data["rostopic"]
        def checkUpdateRate(self, update_rate):
            if update_rate <= 0.0:
                self.raiseError("invalid update_rate")
        @catch_keyerror
        def getUpdateRate(self):
            self.checkUpdateRate(self.data["update_rate"])
            return self.data["update_rate"]
        def checkAccelerometerStatistics(self, noise_density, random_walk):
            if noise_density <= 0.0:
                self.raiseError("invalid accelerometer_noise_density")
            if random_walk <= 0.0:
                self.raiseError("invalid accelerometer_random_walk")
        @catch_keyerror
        def getAccelerometerStatistics(self):
            self.checkAccelerometerStatistics(self.data["accelerometer_noise_density"],
                                              self.data["accelerometer_random_walk"])
            accelUncertaintyDiscrete = self.data["accelerometer_noise_density"]
                                       / math.sqrt(1.0/self.getUpdateRate())
            return accelUncertaintyDiscrete, self.data["accelerometer_random_walk"],
                   self.data["accelerometer_noise_density"]
        (getGyroStatistics: the same with gyroscope_noise_density, gyroscope_random_walk)

``printDetails`` calls getUpdateRate, getAccelerometerStatistics and
getGyroStatistics; kalibr_calibrate_imu_camera's IccImu reads the same getters and
getRosTopic.  Under Python 3 a ``null`` value makes ``None <= 0.0`` raise
``TypeError`` — the mirror keeps that too (it does not catch what Kalibr does not).
"""

from __future__ import annotations

import math

import yaml


class ImuParameters:
    """Kalibr's ``ImuParameters`` getters over a YAML file (see the module docstring)."""

    name = "ImuConfig"

    def __init__(self, yaml_file) -> None:
        self.yaml_file = str(yaml_file)
        try:
            with open(yaml_file) as f:
                self.data = yaml.safe_load(f)
        except Exception:
            self._raise(f"Could not read configuration from {self.yaml_file}")

    def _raise(self, message: str):
        raise RuntimeError(f"[{self.name} Reader]: {message}")

    def _get(self, key: str):
        try:
            return self.data[key]
        except KeyError as e:
            self._raise(f"Field {e} missing in file: {self.yaml_file}")

    def get_ros_topic(self) -> str:
        topic = self._get("rostopic")
        if not isinstance(topic, str):
            self._raise("rostopic has to be a string")
        return topic

    def get_update_rate(self):
        rate = self._get("update_rate")
        if rate <= 0.0:
            self._raise("invalid update_rate")
        return rate

    def _statistics(self, sensor: str):
        density = self._get(f"{sensor}_noise_density")
        walk = self._get(f"{sensor}_random_walk")
        if density <= 0.0:
            self._raise(f"invalid {sensor}_noise_density")
        if walk <= 0.0:
            self._raise(f"invalid {sensor}_random_walk")
        discrete = density / math.sqrt(1.0 / self.get_update_rate())
        return discrete, walk, density

    def get_accelerometer_statistics(self):
        return self._statistics("accelerometer")

    def get_gyro_statistics(self):
        return self._statistics("gyroscope")

    def print_details(self) -> dict:
        """What ``printDetails`` reads (every getter), as a dict."""
        return {
            "rostopic": self.get_ros_topic(),
            "update_rate": self.get_update_rate(),
            "accelerometer": self.get_accelerometer_statistics(),
            "gyroscope": self.get_gyro_statistics(),
        }
