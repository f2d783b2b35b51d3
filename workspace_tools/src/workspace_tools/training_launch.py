"""A training launch file for tests that bring a sim of their own: the cube's training as `./ws run` starts
it, with another sim launch in place of the cube's."""
from __future__ import annotations

from pathlib import Path


def write_cube_training_launch(path: Path, sim_launch: Path, config: Path, results_dir: Path) -> Path:
    """Write to `path` a launch file of robot_rl's train.launch (one env, seed 0, Q-learning, no gui, rviz or
    video) and the cube's training node, with `sim_launch` starting the sim; `resume` and `nepisodes` stay
    launch arguments (defaults false and the config's). Returns `path`."""
    path.write_text(f"""<launch>
  <arg name="resume" default="false"/><arg name="nepisodes" default=""/>
  <include file="$(find robot_rl)/launch/train.launch">
    <arg name="sim_launch" value="{sim_launch}"/><arg name="node_name" value="movingcube_gym"/>
    <arg name="task" value="one_disk_walk"/><arg name="config" value="{config}"/>
    <arg name="nepisodes" value="$(arg nepisodes)"/><arg name="resume" value="$(arg resume)"/>
    <arg name="seed" value="0"/>
    <arg name="results_dir" value="{results_dir}"/><arg name="quiet" value="false"/>
    <arg name="gui" value="false"/><arg name="robot_state_publisher" value="false"/>
    <arg name="rviz" value="false"/><arg name="video" value="false"/>
    <arg name="agent" value="qlearn"/><arg name="agent_config" value=""/><arg name="max_steps" value="0"/>
    <arg name="envs" value="1"/>
  </include>
  <node pkg="moving_cube_training" type="start_training.py" name="movingcube_gym" output="screen" required="true"/>
</launch>""")
    return path
