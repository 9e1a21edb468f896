within UWCoSim;
model ConstantVelocity "Constant-velocity (white-noise acceleration) process model"
  import UWCoSim.Interfaces.RealInput;
  import UWCoSim.Interfaces.RealOutput;
  parameter Real px0(unit = "m") = 2000 "Initial east position";
  parameter Real vx0(unit = "m/s") = 0.5 "Initial east velocity";
  parameter Real py0(unit = "m") = 18000 "Initial north position";
  parameter Real vy0(unit = "m/s") = 0 "Initial north velocity";
  RealInput w_px(unit = "m/s") "Process noise on der(px)";
  RealInput w_vx(unit = "m/s2") "Process noise on der(vx)";
  RealInput w_py(unit = "m/s") "Process noise on der(py)";
  RealInput w_vy(unit = "m/s2") "Process noise on der(vy)";
  RealOutput px(unit = "m", start = px0, fixed = true) "East position";
  RealOutput vx(unit = "m/s", start = vx0, fixed = true) "East velocity";
  RealOutput py(unit = "m", start = py0, fixed = true) "North position";
  RealOutput vy(unit = "m/s", start = vy0, fixed = true) "North velocity";
equation
  der(px) = vx + w_px;
  der(vx) = w_vx;
  der(py) = vy + w_py;
  der(vy) = w_vy;
  annotation (Documentation(info = "<html>
<pre>
der(px) = vx + w_px
der(vx) = w_vx
der(py) = vy + w_py
der(vy) = w_vy
</pre>
</html>"));
end ConstantVelocity;
