within UWCoSim;
model DepthSounder "Terrain depth sounder, eq. (55) row 3"
  import UWCoSim.Interfaces.RealInput;
  import UWCoSim.Interfaces.RealOutput;
  parameter Real meanDepth(unit = "m") = 1000 "Mean depth of the analytic seafloor";
  parameter Real slope = 0.01 "Regional slope of the analytic seafloor (m/m)";
  parameter Real amplitude(unit = "m") = 60 "Relief amplitude of the analytic seafloor";
  parameter Real wavelength(unit = "m") = 5000 "Relief wavelength of the analytic seafloor";
  RealInput x(unit = "m") "True east position";
  RealInput y(unit = "m") "True north position";
  RealInput e_h(unit = "m") "Measurement noise";
  RealOutput depth_m(unit = "m") "Measured seafloor depth (positive down)";
equation
  depth_m = UWCoSim.Functions.seafloorDepth(x, y, meanDepth, slope, amplitude, wavelength)
    + e_h;
  annotation (Documentation(info = "<html>
<pre>depth_m = h_d(x, y) + e_h</pre>
<p><code>h_d</code> is the analytic stand-in <code>UWCoSim.Functions.seafloorDepth</code>.
The project's DepthSounder FMU evaluates the bathymetry map instead (a cubic B-spline over
an external grid, see <code>uwcosim.models.bathymetry</code>); the outputs of the two agree
only in structure, not in value.</p>
</html>"));
end DepthSounder;
