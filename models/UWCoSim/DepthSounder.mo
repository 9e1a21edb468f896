within UWCoSim;
model DepthSounder "Terrain depth sounder, eq. (55) row 3, with outliers and multipath returns"
  import UWCoSim.Interfaces.RealInput;
  import UWCoSim.Interfaces.RealOutput;
  parameter Real meanDepth(unit = "m") = 1000 "Mean depth of the analytic seafloor";
  parameter Real slope = 0.01 "Regional slope of the analytic seafloor (m/m)";
  parameter Real amplitude(unit = "m") = 60 "Relief amplitude of the analytic seafloor";
  parameter Real wavelength(unit = "m") = 5000 "Relief wavelength of the analytic seafloor";
  parameter Real outlierProb = 0 "Probability of an outlier return";
  parameter Real outlierStd(unit = "m") = 0 "Standard deviation of an outlier's extra error";
  parameter Real multipathProb = 0 "Probability of a multipath return";
  parameter Real multipathFactor = 2 "Depth of a multipath return / true depth";
  parameter Real vehicleDepth(unit = "m") = 0 "Vehicle depth (altitude = depth - vehicleDepth)";
  RealInput x(unit = "m") "True east position";
  RealInput y(unit = "m") "True north position";
  RealInput e_h(unit = "m") "Measurement noise";
  RealInput offset_h(unit = "m") "Tide or depth-bias offset added to the depth";
  RealInput u_o "Standard normal selecting outliers and multipath returns";
  RealInput e_o "Standard normal scaling an outlier";
  RealOutput depth_m(unit = "m") "Measured seafloor depth (positive down)";
  RealOutput altitude(unit = "m") "True altitude above the seafloor (no noise)";
protected
  Real h(unit = "m") "Seafloor depth at (x, y)";
  Real c "Phi(u_o)";
equation
  h = UWCoSim.Functions.seafloorDepth(x, y, meanDepth, slope, amplitude, wavelength);
  c = UWCoSim.Functions.normalCdf(u_o);
  depth_m = (if c >= outlierProb and c < outlierProb + multipathProb then multipathFactor*h
    else h) + e_h + offset_h + (if c < outlierProb then outlierStd*e_o else 0);
  altitude = h - vehicleDepth;
  annotation (Documentation(info = "<html>
<pre>depth_m = h_d(x, y) + e_h + offset_h            (eq. 55 with the tide/bias offset)
  + outlierStd*e_o        when Phi(u_o) &lt; outlierProb              (outlier)
  h_d -&gt; multipathFactor*h_d when Phi(u_o) in the next multipathProb (multipath)</pre>
<p><code>h_d</code> is the analytic stand-in <code>UWCoSim.Functions.seafloorDepth</code>.
The project's DepthSounder FMU evaluates the bathymetry map instead (a cubic B-spline over
an external grid, see <code>uwcosim.models.bathymetry</code>); the outputs of the two agree
only in structure, not in value. <code>Phi</code> is <code>UWCoSim.Functions.normalCdf</code>
(an approximation, without the Modelica Standard Library; the FMU uses C's erf).</p>
</html>"));
end DepthSounder;
